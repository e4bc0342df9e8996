//! The renderer's error type.

use thiserror::Error;

/// Everything that can go wrong while setting up or driving the renderer.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum RenderError {
    /// No GPU adapter at all (or none compatible with the window surface).
    #[error(
        "no GPU adapter found{detail}; on a headless Linux machine install a software Vulkan \
         driver (Debian/Ubuntu: `apt-get install -y mesa-vulkan-drivers`)"
    )]
    NoAdapter {
        /// What was tried, e.g. the backends allowed by `WGPU_BACKEND`.
        detail: String,
    },
    /// The only adapter on offer runs on wgpu's GL backend, where the splat
    /// passes cannot read their depth textures (`textureLoad`).
    #[error(
        "the GPU adapter {adapter:?} runs on wgpu's GL backend, which cannot read depth \
         textures as the splat passes do (`textureLoad`); use Vulkan, Metal or DX12 (unset \
         WGPU_BACKEND; on a headless Linux machine: `apt-get install -y mesa-vulkan-drivers`)"
    )]
    GlBackend {
        /// Adapter name.
        adapter: String,
    },
    /// `WGPU_ADAPTER_NAME` was set but no adapter's name contains it.
    #[error(
        "WGPU_ADAPTER_NAME={wanted:?} matches no adapter; available: {}",
        available.join(", ")
    )]
    AdapterNotFound {
        /// The requested (lower-cased) name fragment.
        wanted: String,
        /// Names of the adapters that exist.
        available: Vec<String>,
    },
    /// The adapter refused to create a device.
    #[error("the GPU adapter {adapter:?} could not create a device: {source}")]
    RequestDevice {
        /// Adapter name.
        adapter: String,
        /// wgpu's reason.
        source: wgpu::RequestDeviceError,
    },
    /// The device reported an error outside any call that returns one (a
    /// validation error wgpu would otherwise panic on), or was lost
    /// ([`crate::GpuContext::check`]).
    #[error("the GPU device failed: {0}")]
    Device(String),
    /// A width or height of zero or beyond the device's texture limit.
    #[error("render size {width}×{height} is invalid (each side must be 1..={max})")]
    InvalidSize {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
        /// The device's `max_texture_dimension_2d`.
        max: u32,
    },
    /// A splat with a non-finite position or normal, a zero normal or a non-positive radius.
    #[error("splat {index} is invalid: {reason}")]
    InvalidSplat {
        /// Index in the uploaded slice.
        index: usize,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// More splats than one storage buffer binding can hold on this device.
    #[error(
        "{count} splats need {bytes} bytes, more than this device's storage binding limit of {max} bytes"
    )]
    TooManySplats {
        /// Requested splat count.
        count: usize,
        /// Bytes they need.
        bytes: u64,
        /// Device limit.
        max: u64,
    },
    /// Working memory of the compute splat path past this device's storage
    /// binding limit (a resolution or splat count it cannot splat in compute).
    #[error(
        "the compute splat path's {what} need {bytes} bytes, more than this device's storage binding limit of {max} bytes: lower the resolution or use --splats raster"
    )]
    ComputeLimit {
        /// Which buffer: "pixel sums", "splat rectangles" or "tile lists".
        what: &'static str,
        /// Bytes it needs.
        bytes: u64,
        /// The device's `max_storage_buffer_binding_size` (or `max_buffer_size`).
        max: u64,
    },
    /// A GPU-resident splat source whose buffers cannot serve as one.
    #[error("invalid GPU splat source: {0}")]
    InvalidSource(&'static str),
    /// A camera that cannot be projected (non-finite, eye on target, bad clip planes).
    #[error("invalid camera: {0}")]
    InvalidCamera(&'static str),
    /// Shading parameters that would draw garbage (non-finite, negative where
    /// a length, weight or colour is meant).
    #[error("invalid shading: {0}")]
    InvalidShading(&'static str),
    /// An environment or background image that is empty or larger than the
    /// device's textures.
    #[error("invalid texture {name}: {reason}")]
    InvalidTexture {
        /// Which texture.
        name: &'static str,
        /// Why.
        reason: String,
    },
    /// Scene geometry with a non-finite or negative value, or a degenerate shape.
    #[error("invalid scene geometry: {0}")]
    InvalidGeometry(String),
    /// Reading a texture back to the CPU failed.
    #[error("GPU readback failed: {0}")]
    Readback(String),
    /// Loading an image file failed.
    #[error("cannot load {path}: {source}")]
    Image {
        /// The file.
        path: String,
        /// The decoder's reason.
        source: image::ImageError,
    },
}

/// Result alias for this crate.
pub type Result<T, E = RenderError> = std::result::Result<T, E>;
