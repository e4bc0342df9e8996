//! Shading parameters, debug views, and a CPU reference of the per-pixel shading
//! (eq. 38–40) that the compute pass evaluates.

use glam::{Mat4, Vec2, Vec3};

use crate::textures::{Environment, equirect_uv, sample_bilinear};

/// What the shade pass writes per pixel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum View {
    /// Eq. 40: Fresnel-weighted environment reflection plus absorbed, refracted background.
    #[default]
    Shaded,
    /// The normalised normal as colour (n · 0.5 + 0.5); black where nothing is drawn.
    Normals,
    /// The weight sum Σw as grey (scaled by [`Shading::weight_scale`]); holes are black.
    Weights,
    /// Linear depth of the visible surface on a log scale between the camera's clip planes; background black.
    Depth,
}

impl View {
    /// All views, in the order a UI cycles through them.
    pub const ALL: [View; 4] = [View::Shaded, View::Normals, View::Weights, View::Depth];

    pub(crate) fn code(self) -> f32 {
        match self {
            View::Shaded => 0.0,
            View::Normals => 1.0,
            View::Weights => 2.0,
            View::Depth => 3.0,
        }
    }
}

/// Parameters of the splat passes and of the shading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shading {
    /// Debug view or the shaded image.
    pub view: View,
    /// ε: the visibility pass pushes depth back by this world-space distance along
    /// the view ray; splats within ε behind the front surface blend with it.
    pub depth_epsilon: f32,
    /// μ of eq. 39: background offset per unit of reflection-vector x/y, in
    /// fractions of the viewport.
    pub refraction: f32,
    /// c_fluid of eq. 40: the fraction of background light that passes the fluid, per channel.
    pub fluid_colour: Vec3,
    /// Beer–Lambert absorption σ per world unit and channel: light through
    /// a thickness t of fluid keeps exp(−σ t) on top of `fluid_colour`, so
    /// thin sheets look light and deep water coloured. The thickness runs
    /// from the front surface to the farthest back-facing splat, or to the
    /// scene geometry where that is nearer (an extra splat pass, run only
    /// when some σ > 0). Zero,
    /// the default, is the thesis's eq. 40.
    pub absorption: Vec3,
    /// Σw shown as white in [`View::Weights`].
    pub weight_scale: f32,
    /// Multiplies the Fresnel term of eq. 38–40 (1 = the thesis).
    pub reflectivity: f32,
    /// Drops splats whose normal points away from the eye, as Botsch et al.
    /// (2005) do: the back of a closed surface, or of a thin sheet within ε
    /// behind its front, would otherwise blend into it with an opposite
    /// normal, and holes in the front would show the back from inside. Turn
    /// it off for surfels without a consistent outward orientation.
    pub cull_back_faces: bool,
}

impl Default for Shading {
    fn default() -> Self {
        Self {
            view: View::Shaded,
            depth_epsilon: 0.01,
            refraction: 0.05,
            fluid_colour: Vec3::new(0.55, 0.75, 0.85),
            absorption: Vec3::ZERO,
            weight_scale: 2.0,
            reflectivity: 1.0,
            cull_back_faces: true,
        }
    }
}

/// The demo's Beer–Lambert absorption per metre (red, green, blue): water
/// stylised about 15 to 40 times stronger than real water's (0.45, 0.06,
/// 0.02) per metre, so that a tank tens of centimetres deep shows its
/// depth: 5 cm keeps 74 %, 91 %, 97 % of the light behind it, 30 cm 17 %,
/// 58 %, 81 %.
pub const WATER_ABSORPTION: Vec3 = Vec3::new(6.0, 1.8, 0.7);

impl Shading {
    /// The demo's water for a fluid of smoothing length `h`: ε = h/2 (the
    /// surfels' scale), and a colour that comes from Beer–Lambert absorption
    /// through the water's thickness ([`WATER_ABSORPTION`]) rather than a
    /// flat tint.
    pub fn water(h: f32) -> Self {
        Self {
            depth_epsilon: 0.5 * h,
            fluid_colour: Vec3::new(0.92, 0.97, 1.0),
            absorption: WATER_ABSORPTION,
            // The thesis's Fresnel term (eq. 38) reflects 60 % at the
            // cameras' 27° downward view, where water reflects about 7 %
            // (Schlick): at 1 the sky's reflection whitens the whole surface.
            reflectivity: 0.4,
            ..Default::default()
        }
    }

    /// Checks the fields the shaders compute with: with a NaN or infinite
    /// value there, what a pass writes (a NaN depth, a NaN colour) is up to
    /// the driver, not the thesis's shading.
    ///
    /// # Errors
    /// [`RenderError::InvalidShading`](crate::RenderError::InvalidShading)
    /// naming the field: `depth_epsilon` must be finite and ≥ 0,
    /// `refraction` finite, `fluid_colour` and `absorption` finite and ≥ 0
    /// per channel,
    /// `weight_scale` finite and > 0 (not subnormal), `reflectivity` finite
    /// and ≥ 0.
    pub fn validate(&self) -> crate::Result<()> {
        use crate::RenderError::InvalidShading;
        let non_negative = |v: f32| v.is_finite() && v >= 0.0;
        if !non_negative(self.depth_epsilon) {
            return Err(InvalidShading("depth_epsilon must be finite and >= 0"));
        }
        if !self.refraction.is_finite() {
            return Err(InvalidShading("refraction must be finite"));
        }
        if !self.fluid_colour.to_array().into_iter().all(non_negative) {
            return Err(InvalidShading(
                "fluid_colour must be finite and >= 0 in every channel",
            ));
        }
        if !self.absorption.to_array().into_iter().all(non_negative) {
            return Err(InvalidShading(
                "absorption must be finite and >= 0 in every channel",
            ));
        }
        // A subnormal scale flushes to 0 on GPUs, and Σw / 0 is NaN.
        if !(self.weight_scale.is_normal() && self.weight_scale > 0.0) {
            return Err(InvalidShading(
                "weight_scale must be finite and > 0 (a normal float)",
            ));
        }
        if !non_negative(self.reflectivity) {
            return Err(InvalidShading("reflectivity must be finite and >= 0"));
        }
        Ok(())
    }
}

/// The Fresnel approximation of eq. 38, R = (0.5 + 0.5 r·l)², with `l` the unit
/// viewing direction from the eye: 0 looking straight onto the surface, 1 at
/// grazing incidence, as the thesis describes.
pub fn fresnel(r: Vec3, l: Vec3) -> f32 {
    let f = 0.5 + 0.5 * r.dot(l);
    f * f
}

/// The fraction of the light behind the fluid that reaches the eye through
/// `thickness` of it, per channel: c_fluid · exp(−σ t) (eq. 40 with
/// Beer–Lambert absorption).
pub fn transmittance(shading: &Shading, thickness: f32) -> Vec3 {
    shading.fluid_colour * (-shading.absorption * thickness).exp()
}

/// Eq. 40 at one pixel, exactly as the compute pass evaluates it without
/// scene geometry or absorption (the screen-space backdrop refracted):
/// `normal` is the (normalised) splatted world normal, `dir` the unit world
/// direction of the pixel's view ray, `uv` the pixel centre in viewport
/// fractions, `view` the camera's world → view matrix. `None` for `normal` is a
/// pixel no splat covers: the plain background.
pub fn shade_pixel(
    normal: Option<Vec3>,
    dir: Vec3,
    uv: Vec2,
    view: &Mat4,
    env: &Environment,
    shading: &Shading,
) -> Vec3 {
    let Some(n) = normal else {
        return sample_bilinear(&env.background, uv, false);
    };
    let r = reflect(dir, n);
    let reflected = sample_bilinear(&env.environment, equirect_uv(r), true);
    let rv = view.transform_vector3(r);
    let offset = shading.refraction * Vec2::new(-rv.x, rv.y);
    let refracted = sample_bilinear(&env.background, uv + offset, false);
    shading.reflectivity * fresnel(r, dir) * reflected + shading.fluid_colour * refracted
}

/// Mirror reflection of direction `d` about unit normal `n` (WGSL `reflect`).
pub fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - 2.0 * d.dot(n) * n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shading_that_would_draw_garbage_is_an_error_naming_the_field() {
        let ok = Shading::default();
        assert!(ok.validate().is_ok());
        // The ends of the demo panel's sliders (ε 0–0.1, μ 0–0.2,
        // reflectivity 0–2, colour 0–1), and a negative μ (a mirrored offset).
        for edge in [
            Shading {
                depth_epsilon: 0.0,
                refraction: 0.0,
                reflectivity: 0.0,
                fluid_colour: Vec3::ZERO,
                ..ok
            },
            Shading {
                depth_epsilon: 0.1,
                refraction: 0.2,
                reflectivity: 2.0,
                fluid_colour: Vec3::ONE,
                ..ok
            },
            Shading {
                refraction: -0.2,
                ..ok
            },
        ] {
            assert!(edge.validate().is_ok(), "{edge:?}");
        }
        let cases = [
            (
                Shading {
                    depth_epsilon: f32::NAN,
                    ..ok
                },
                "depth_epsilon",
            ),
            (
                Shading {
                    depth_epsilon: -0.01,
                    ..ok
                },
                "depth_epsilon",
            ),
            (
                Shading {
                    refraction: f32::INFINITY,
                    ..ok
                },
                "refraction",
            ),
            (
                Shading {
                    fluid_colour: Vec3::new(0.5, f32::NAN, 0.5),
                    ..ok
                },
                "fluid_colour",
            ),
            (
                Shading {
                    fluid_colour: Vec3::new(0.5, 0.5, -0.1),
                    ..ok
                },
                "fluid_colour",
            ),
            (
                Shading {
                    absorption: Vec3::new(1.0, -1.0, 1.0),
                    ..ok
                },
                "absorption",
            ),
            (
                Shading {
                    absorption: Vec3::new(1.0, 1.0, f32::NAN),
                    ..ok
                },
                "absorption",
            ),
            (
                Shading {
                    weight_scale: 0.0,
                    ..ok
                },
                "weight_scale",
            ),
            (
                Shading {
                    weight_scale: f32::NAN,
                    ..ok
                },
                "weight_scale",
            ),
            (
                Shading {
                    weight_scale: 1e-45,
                    ..ok
                },
                "weight_scale",
            ),
            (
                Shading {
                    reflectivity: f32::NEG_INFINITY,
                    ..ok
                },
                "reflectivity",
            ),
            (
                Shading {
                    reflectivity: -1.0,
                    ..ok
                },
                "reflectivity",
            ),
        ];
        for (bad, field) in cases {
            let err = bad.validate().unwrap_err().to_string();
            assert!(err.contains(field), "{bad:?}: {err}");
        }
    }

    #[test]
    fn fresnel_limits_follow_the_thesis() {
        let down = -Vec3::Y;
        let r = reflect(down, Vec3::Y);
        assert!(
            fresnel(r, down).abs() < 1e-6,
            "straight down: no reflection"
        );
        let grazing = Vec3::new(1.0, -1e-3, 0.0).normalize();
        assert!(fresnel(reflect(grazing, Vec3::Y), grazing) > 0.999);
    }
}
