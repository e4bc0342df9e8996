//! # splat-render
//!
//! Draws any set of surfels with wgpu by two-pass point splatting (Vesterlund
//! 2004, 3.2.2, 3.2.3 and 4.2.2; Botsch et al. 2005):
//!
//! 0. **scene pass**: the backdrop and any opaque [`SceneGeometry`] (a
//!    container, obstacles, the ground), whose depth the splats are tested
//!    against and whose image the fluid refracts;
//! 1. **visibility pass**: each [`Splat`] is drawn as the square bounding its
//!    disc in the disc's own plane, projected, so the rasterizer gives each
//!    pixel the plane's exact depth (pushed back by ε, the corners moved along
//!    their view rays) and the depth test runs before the fragment shader,
//!    which intersects the view ray with the disc (an exact,
//!    perspective-correct ellipse) and discards the pixels outside it;
//! 2. **attribute pass**: the same splats, depth-tested against pass 1 without
//!    writing depth, add w·(normal, 1) into a float target, w the alpha mask of
//!    eq. 37;
//! 3. **normalise and shade** (a compute pass): A = Σ Aᵢwᵢ / Σ wᵢ per pixel and
//!    the image-based shading of eq. 38–40, or a debug [`View`]; with
//!    [`Shading::absorption`] a back surface pass measures the fluid's
//!    thickness and the refracted light is absorbed along it (Beer–Lambert).
//!
//! A [`GpuContext`] is created headless (tests, frame writers) or for a window
//! surface. The crate knows nothing of SPH.
//!
//! ```no_run
//! use glam::Vec3;
//! use splat_render::{Camera, Environment, GpuContext, Shading, Splat, SplatRenderer};
//!
//! let ctx = GpuContext::headless()?;
//! let mut renderer = SplatRenderer::new(&ctx, 640, 480, &Environment::procedural())?;
//! renderer.upload(&ctx, &[Splat::new(Vec3::ZERO, Vec3::Z, 0.5)])?;
//! let camera = Camera::looking_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO);
//! renderer.render(&ctx, &camera, &Shading::default())?;
//! renderer.read_image(&ctx)?.save("splat.png").expect("writable");
//! # Ok::<(), splat_render::RenderError>(())
//! ```

mod camera;
mod context;
mod error;
pub mod geometry;
pub mod layout;
mod readback;
mod renderer;
pub mod shading;
mod splat;
pub mod textures;

pub use camera::Camera;
pub use context::{GpuContext, instance_from_env};
pub use error::{RenderError, Result};
pub use geometry::{Backdrop, Material, Mesh, Object, SceneGeometry};
pub use readback::{Accumulation, read_texture_rgba8};
pub use renderer::{OUTPUT_FORMAT, SplatPath, SplatRenderer};
pub use shading::{Shading, View, WATER_ABSORPTION};
pub use splat::{MAX_SPLAT_EXTENT, Splat, alpha_mask};
pub use textures::Environment;

pub use wgpu;
/// Re-export of the GPU pass profiler [`SplatRenderer::encode_profiled`] takes.
pub use wgpu_profiler;
