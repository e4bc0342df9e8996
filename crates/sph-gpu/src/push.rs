//! [`RayPush`]: the demo's push near a ray, one field for the CPU's push
//! processor and both GPU solvers' shaders (`shaders/push.wgsl`).

use glam::Vec3;

use crate::grid::GpuError;

/// A push of the fluid near a ray (the demo's Ctrl+drag): each particle
/// within `radius` of the ray through `origin` along the unit `dir` is
/// accelerated by `acceleration` × (1 − q)², q = (its distance from the ray
/// / `radius`)²; the same field on the CPU
/// ([`RayPush::acceleration_at`]) and on the GPU (`shaders/push.wgsl`, in
/// [`crate::GpuPbf::set_push`]'s predict pass and
/// [`crate::GpuSolver::set_push`]'s forces pass).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayPush {
    /// A point on the ray (m).
    pub origin: Vec3,
    /// The ray's direction (unit).
    pub dir: Vec3,
    /// The acceleration on the ray (m/s²).
    pub acceleration: Vec3,
    /// How far from the ray it reaches (m).
    pub radius: f32,
}

impl RayPush {
    /// Checks the push is one the field is defined for.
    ///
    /// # Errors
    /// [`GpuError::Invalid`] for a push that is not finite, a direction
    /// that is not unit length or a radius that is not positive (where
    /// [`RayPush::acceleration_at`] would be NaN).
    pub fn validate(&self) -> Result<(), GpuError> {
        let finite =
            self.origin.is_finite() && self.dir.is_finite() && self.acceleration.is_finite();
        if !finite || (self.dir.length() - 1.0).abs() > 1e-3 {
            return Err(GpuError::Invalid(
                "a push needs a finite origin and acceleration and a unit direction",
            ));
        }
        if !(self.radius.is_finite() && self.radius > 0.0) {
            return Err(GpuError::Invalid("a push's radius must be finite and > 0"));
        }
        Ok(())
    }

    /// The push's acceleration at `x`, for a push that
    /// [`validates`](RayPush::validate).
    pub fn acceleration_at(&self, x: Vec3) -> Vec3 {
        let d = x - self.origin;
        let off = d - d.dot(self.dir) * self.dir;
        let q = off.length_squared() / (self.radius * self.radius);
        if q >= 1.0 {
            Vec3::ZERO
        } else {
            self.acceleration * ((1.0 - q) * (1.0 - q))
        }
    }
}

/// A push as the shaders take it: (origin, radius), (direction, 0),
/// (acceleration, 0); zeros without one.
///
/// # Errors
/// [`GpuError::Invalid`] for a push that is not finite, a direction that is
/// not unit length or a radius that is not positive.
pub(crate) fn push_uniforms(push: Option<RayPush>) -> Result<[[f32; 4]; 3], GpuError> {
    let Some(p) = push else {
        return Ok([[0.0; 4]; 3]);
    };
    p.validate()?;
    Ok([
        p.origin.extend(p.radius).to_array(),
        p.dir.extend(0.0).to_array(),
        p.acceleration.extend(0.0).to_array(),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A push the field is not defined for is an error from `validate`
    /// (and so from both solvers' `set_push`), where `acceleration_at` was
    /// NaN at a radius of 0; a valid one pushes hardest on its ray.
    #[test]
    fn bad_pushes_are_errors() {
        let good = RayPush {
            origin: Vec3::ZERO,
            dir: Vec3::X,
            acceleration: Vec3::Y,
            radius: 0.1,
        };
        good.validate().unwrap();
        assert_eq!(good.acceleration_at(Vec3::new(0.5, 0.0, 0.0)), Vec3::Y);
        for bad in [
            RayPush {
                radius: 0.0,
                ..good
            },
            RayPush {
                radius: f32::NAN,
                ..good
            },
            RayPush {
                dir: Vec3::ZERO,
                ..good
            },
            RayPush {
                origin: Vec3::NAN,
                ..good
            },
            RayPush {
                acceleration: Vec3::INFINITY,
                ..good
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
            assert!(push_uniforms(Some(bad)).is_err(), "{bad:?}");
        }
    }
}
