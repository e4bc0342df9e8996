//! [`Splat`]: the renderer's input primitive, and its GPU layout.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use crate::error::{RenderError, Result};

/// One oriented disc to draw: a surfel as any surface extractor produces it.
///
/// The renderer knows nothing of where splats come from; `surfel-extract`'s
/// surfels convert one to one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Splat {
    /// Centre (world space).
    pub position: Vec3,
    /// Unit normal (world space). It is normalised on upload.
    pub normal: Vec3,
    /// Disc radius; also the support `h` of the alpha mask (eq. 37).
    pub radius: f32,
}

impl Splat {
    /// A splat at `position` with `normal` and `radius`.
    pub fn new(position: Vec3, normal: Vec3, radius: f32) -> Self {
        Self {
            position,
            normal,
            radius,
        }
    }
}

/// The largest splat coordinate or radius [`crate::SplatRenderer::upload`]
/// accepts: the shaders square lengths in f32, which overflows beyond
/// about 1.8e19.
pub const MAX_SPLAT_EXTENT: f32 = 1e18;

/// GPU layout: two 16-byte vectors (WGSL `vec3` in storage is 16-aligned).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct GpuSplat {
    pub position_radius: [f32; 4],
    pub normal: [f32; 4],
}

impl GpuSplat {
    /// Validates and converts splat `index`.
    pub(crate) fn from_splat(index: usize, s: &Splat) -> Result<Self> {
        let invalid = |reason| Err(RenderError::InvalidSplat { index, reason });
        if !s.position.is_finite() {
            return invalid("position is not finite");
        }
        if s.position.abs().max_element() > MAX_SPLAT_EXTENT {
            return invalid(
                "position lies beyond 1e18 of the origin: the shaders square it in f32",
            );
        }
        if !(s.radius.is_finite() && s.radius > 0.0) {
            return invalid("radius must be finite and > 0");
        }
        if s.radius > MAX_SPLAT_EXTENT {
            return invalid(
                "radius exceeds 1e18: the shaders square it in f32 (3e38 drew nothing)",
            );
        }
        let n = s.normal.normalize_or_zero();
        if n == Vec3::ZERO || !n.is_finite() {
            return invalid("normal is zero or not finite");
        }
        Ok(Self {
            position_radius: s.position.extend(s.radius).to_array(),
            normal: n.extend(0.0).to_array(),
        })
    }
}

/// The alpha mask of eq. 37 with support `h` at distance `r` from the centre:
/// w = (h² − r²)³ / h⁶ for r ≤ h, 0 beyond. The shaders evaluate the same
/// expression as (1 − r²/h²)³.
pub fn alpha_mask(r: f32, h: f32) -> f32 {
    if r > h || h <= 0.0 {
        return 0.0;
    }
    let m = 1.0 - (r * r) / (h * h);
    m * m * m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mask_matches_eq_37() {
        let h = 0.3f64;
        for i in 0..=10 {
            let r = h * i as f64 / 10.0;
            let eq37 = (h * h - r * r).powi(3) / h.powi(6);
            assert!((alpha_mask(r as f32, h as f32) as f64 - eq37).abs() < 1e-6);
        }
        assert_eq!(alpha_mask(0.31, 0.3), 0.0);
    }

    #[test]
    fn invalid_splats_are_named() {
        let ok = Splat::new(Vec3::ZERO, Vec3::Z, 1.0);
        assert!(GpuSplat::from_splat(0, &ok).is_ok());
        for bad in [
            Splat {
                position: Vec3::NAN,
                ..ok
            },
            Splat { radius: 0.0, ..ok },
            Splat {
                radius: f32::INFINITY,
                ..ok
            },
            Splat {
                normal: Vec3::ZERO,
                ..ok
            },
            Splat { radius: 3e38, ..ok },
            Splat {
                position: Vec3::X * 1e30,
                ..ok
            },
        ] {
            let err = GpuSplat::from_splat(7, &bad).unwrap_err().to_string();
            assert!(err.starts_with("splat 7 is invalid"), "{err}");
        }
    }
}
