//! The environment map and the background image of the shading model (eq. 40),
//! made procedurally by this crate (and stored as PNGs in `assets/textures/`).

use std::f32::consts::PI;
use std::path::Path;

use glam::{Vec2, Vec3};
use image::{Rgba, RgbaImage};

use crate::error::{RenderError, Result};

/// The two images the shading samples: an equirectangular environment map
/// (`t_env`, looked up by the reflection vector) and the background seen
/// through the fluid (`t_back`, looked up in screen space).
#[derive(Clone, Debug)]
pub struct Environment {
    /// Equirectangular map: u = azimuth (0 at −z, growing towards +x), v = polar angle from +y.
    pub environment: RgbaImage,
    /// Screen-space background, stretched over the viewport.
    pub background: RgbaImage,
}

impl Environment {
    /// The procedural sky-and-floor environment (1024×512) and tiled background (1024×1024).
    pub fn procedural() -> Self {
        Self {
            environment: procedural_environment(1024, 512),
            background: procedural_background(1024, 1024),
        }
    }

    /// Loads `environment.png` and `background.png` from `dir` (e.g. `assets/textures`).
    ///
    /// # Errors
    /// [`RenderError::Image`] if a file is missing or not an image,
    /// [`RenderError::InvalidTexture`] if one is empty.
    pub fn load(dir: &Path) -> Result<Self> {
        let load = |name: &str| -> Result<RgbaImage> {
            let path = dir.join(name);
            image::open(&path)
                .map(|i| i.to_rgba8())
                .map_err(|source| RenderError::Image {
                    path: path.display().to_string(),
                    source,
                })
        };
        let env = Self {
            environment: load("environment.png")?,
            background: load("background.png")?,
        };
        env.validate(u32::MAX)?;
        Ok(env)
    }

    /// Checks that both images have pixels and no side above `max_side` (the
    /// device's `max_texture_dimension_2d`).
    pub(crate) fn validate(&self, max_side: u32) -> Result<()> {
        for (name, img) in [
            ("environment", &self.environment),
            ("background", &self.background),
        ] {
            if img.width() == 0 || img.height() == 0 {
                return Err(RenderError::InvalidTexture {
                    name,
                    reason: "it has no pixels".into(),
                });
            }
            if img.width().max(img.height()) > max_side {
                return Err(RenderError::InvalidTexture {
                    name,
                    reason: format!(
                        "{}×{} exceeds the device's largest texture side, {max_side}",
                        img.width(),
                        img.height()
                    ),
                });
            }
        }
        Ok(())
    }
}

/// Equirectangular texture coordinates of unit direction `d` (the shaders use the same).
pub fn equirect_uv(d: Vec3) -> Vec2 {
    Vec2::new(
        0.5 + d.x.atan2(-d.z) / (2.0 * PI),
        d.y.clamp(-1.0, 1.0).acos() / PI,
    )
}

fn to_rgba(c: Vec3) -> Rgba<u8> {
    let q = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
    Rgba([q(c.x), q(c.y), q(c.z), 255])
}

/// A sky (horizon to zenith gradient with a sun) above a checkered floor.
pub fn procedural_environment(width: u32, height: u32) -> RgbaImage {
    let sun = crate::geometry::SUN.normalize();
    RgbaImage::from_fn(width, height, |x, y| {
        let phi = ((x as f32 + 0.5) / width as f32 - 0.5) * 2.0 * PI;
        let theta = (y as f32 + 0.5) / height as f32 * PI;
        let d = Vec3::new(
            theta.sin() * phi.sin(),
            theta.cos(),
            -theta.sin() * phi.cos(),
        );
        let horizon = Vec3::new(0.86, 0.9, 0.95);
        let sky = horizon.lerp(Vec3::new(0.22, 0.42, 0.8), d.y.max(0.0).sqrt());
        let s = d.dot(sun).max(0.0);
        let sky = sky + Vec3::splat(s.powf(600.0) * 2.0 + s.powf(12.0) * 0.25);
        let checker = ((phi * 8.0 / PI).floor() as i32 + (theta * 24.0 / PI).floor() as i32) & 1;
        let floor = if checker == 0 {
            Vec3::new(0.42, 0.38, 0.33)
        } else {
            Vec3::new(0.3, 0.27, 0.24)
        };
        let floor = floor.lerp(horizon, (1.0 + d.y * 6.0).clamp(0.0, 1.0) * 0.6);
        let t = ((d.y + 0.02) * 25.0).clamp(0.0, 1.0);
        to_rgba(floor.lerp(sky, t))
    })
}

/// Light and blue-grey tiles with dark grout: refraction shows as bent lines.
pub fn procedural_background(width: u32, height: u32) -> RgbaImage {
    let tiles = 16.0;
    RgbaImage::from_fn(width, height, |x, y| {
        let u = (x as f32 + 0.5) / width as f32 * tiles;
        let v = (y as f32 + 0.5) / height as f32 * tiles;
        let checker = (u.floor() as i32 + v.floor() as i32) & 1;
        let base = if checker == 0 {
            Vec3::new(0.93, 0.9, 0.84)
        } else {
            Vec3::new(0.55, 0.63, 0.72)
        };
        let edge = (u - u.round()).abs().min((v - v.round()).abs());
        let grout = (edge * 40.0).clamp(0.0, 1.0);
        let shade = 0.85 + 0.15 * (v / tiles);
        to_rgba(Vec3::new(0.2, 0.2, 0.22).lerp(base * shade, grout))
    })
}

/// Bilinear lookup at `uv` as a wgpu `Linear` sampler does (texel centres at
/// half-integers), with the u coordinate repeating when `repeat_u` and both
/// clamped to the edge otherwise. Returns linear 0..1 RGB; an image without
/// pixels reads as black.
pub fn sample_bilinear(img: &RgbaImage, uv: Vec2, repeat_u: bool) -> Vec3 {
    let (w, h) = (img.width() as i64, img.height() as i64);
    if w == 0 || h == 0 {
        return Vec3::ZERO;
    }
    let x = uv.x * w as f32 - 0.5;
    let y = uv.y * h as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let texel = |i: i64, j: i64| {
        let i = if repeat_u {
            i.rem_euclid(w)
        } else {
            i.clamp(0, w - 1)
        };
        let j = j.clamp(0, h - 1);
        let p = img.get_pixel(i as u32, j as u32).0;
        Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32) / 255.0
    };
    let (i, j) = (x0 as i64, y0 as i64);
    let top = texel(i, j).lerp(texel(i + 1, j), fx);
    let bottom = texel(i, j + 1).lerp(texel(i + 1, j + 1), fx);
    top.lerp(bottom, fy)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equirect_covers_the_sphere() {
        assert!((equirect_uv(Vec3::Y).y).abs() < 1e-6);
        assert!((equirect_uv(-Vec3::Y).y - 1.0).abs() < 1e-6);
        let front = equirect_uv(-Vec3::Z);
        assert!((front - Vec2::new(0.5, 0.5)).length() < 1e-6);
        assert!((equirect_uv(Vec3::X).x - 0.75).abs() < 1e-6);
    }

    #[test]
    fn bilinear_reproduces_texels_at_centres() {
        let img = procedural_background(64, 32);
        let p = img.get_pixel(10, 7).0;
        let s = sample_bilinear(&img, Vec2::new(10.5 / 64.0, 7.5 / 32.0), false);
        assert!(
            (s * 255.0 - Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32))
                .abs()
                .max_element()
                < 1e-3
        );
    }

    #[test]
    fn empty_or_oversized_images_are_errors() {
        assert_eq!(
            sample_bilinear(&RgbaImage::new(0, 0), Vec2::splat(0.5), true),
            Vec3::ZERO
        );
        let env = Environment::procedural();
        let side = env.environment.width().max(env.environment.height());
        assert!(env.validate(side).is_ok());
        let e = env.validate(side - 1).unwrap_err().to_string();
        assert!(e.contains("largest texture side"), "{e}");
        let empty = Environment {
            background: RgbaImage::new(0, 4),
            ..env
        };
        assert!(empty.validate(u32::MAX).is_err());
    }

    #[test]
    fn stored_assets_are_the_procedural_ones() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/textures");
        let stored = Environment::load(&dir).expect("assets/textures exist");
        let made = Environment::procedural();
        for (a, b) in [
            (&stored.environment, &made.environment),
            (&stored.background, &made.background),
        ] {
            assert_eq!(a.dimensions(), b.dimensions());
            // Transcendentals may differ by an ulp across libms: allow one level.
            let worst = a
                .as_raw()
                .iter()
                .zip(b.as_raw())
                .map(|(x, y)| x.abs_diff(*y))
                .max();
            assert!(
                worst.unwrap_or(0) <= 1,
                "assets differ from the generator: regenerate them"
            );
        }
    }
}
