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
    /// The push's acceleration at `x`.
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
    let finite = p.origin.is_finite() && p.dir.is_finite() && p.acceleration.is_finite();
    if !finite || (p.dir.length() - 1.0).abs() > 1e-3 {
        return Err(GpuError::Invalid(
            "a push needs a finite origin and acceleration and a unit direction",
        ));
    }
    if !(p.radius.is_finite() && p.radius > 0.0) {
        return Err(GpuError::Invalid("a push's radius must be finite and > 0"));
    }
    Ok([
        p.origin.extend(p.radius).to_array(),
        p.dir.extend(0.0).to_array(),
        p.acceleration.extend(0.0).to_array(),
    ])
}
