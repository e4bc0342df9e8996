//! A reference ray caster of the iso-surface c(x) = k_iso: what the surfels
//! approximate, found without surfels. Renderers compare their images with it
//! (silhouette, normals, shading).

use glam::Vec3;

use crate::field::ColourField;

/// Where a ray first meets the iso-surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// Distance along the (unit) ray direction.
    pub t: f32,
    /// The hit point.
    pub position: Vec3,
    /// Unit outward normal −∇c/|∇c| at the hit.
    pub normal: Vec3,
}

/// Casts rays against c(x) = `iso` of one field: march in steps of `step`
/// through the field's support box (outside it c = 0), then 30 bisections on the
/// first sign change of c − iso.
///
/// A surface sheet thinner than `step` along a ray may be stepped over; use a
/// step well below h (h/8 resolves every feature the poly6 field can form).
#[derive(Debug)]
pub struct Raycaster<'a> {
    field: &'a ColourField,
    iso: f32,
    step: f32,
    bounds: Option<(Vec3, Vec3)>,
}

impl<'a> Raycaster<'a> {
    /// A ray caster for `field` at `iso` marching in steps of `step` (clamped to
    /// at least h/1000; h/8 if not finite and positive).
    pub fn new(field: &'a ColourField, iso: f32, step: f32) -> Self {
        let h = field.h();
        let step = if step.is_finite() && step > 0.0 {
            step.max(h * 1e-3)
        } else {
            h / 8.0
        };
        Self {
            field,
            iso,
            step,
            bounds: field.support_bounds(),
        }
    }

    /// The first crossing into the fluid (c rising through `iso`) along
    /// `origin + t·dir`, t > 0, or `None` if the ray misses (or is not finite).
    pub fn cast(&self, origin: Vec3, dir: Vec3) -> Option<RayHit> {
        let dir = dir.try_normalize()?;
        let (lo, hi) = self.bounds?;
        if !origin.is_finite() {
            return None;
        }
        // Slab test against the support box.
        let inv = dir.recip();
        let (t0, t1) = ((lo - origin) * inv, (hi - origin) * inv);
        let enter = t0.min(t1).max_element().max(0.0);
        let exit = t0.max(t1).min_element();
        if enter.is_nan() || exit.is_nan() || enter > exit {
            return None;
        }
        let f = |t: f32| self.field.sample(origin + t * dir).c - self.iso;
        if f(enter) >= 0.0 {
            // The origin is inside the fluid: report the entry point itself.
            return Some(self.hit(origin, dir, enter));
        }
        // Step k spans enter + [k, k + 1]·step: counted, so the march ends
        // even where a step is below the f32 resolution of t.
        let steps = ((exit - enter) / self.step).ceil() as u64;
        for k in 0..steps {
            let a = enter + k as f32 * self.step;
            let b = (enter + (k + 1) as f32 * self.step).min(exit);
            let fb = f(b);
            if fb >= 0.0 {
                let (mut lo_t, mut hi_t) = (a, b);
                for _ in 0..30 {
                    let mid = 0.5 * (lo_t + hi_t);
                    if f(mid) >= 0.0 {
                        hi_t = mid;
                    } else {
                        lo_t = mid;
                    }
                }
                return Some(self.hit(origin, dir, 0.5 * (lo_t + hi_t)));
            }
        }
        None
    }

    fn hit(&self, origin: Vec3, dir: Vec3, t: f32) -> RayHit {
        let position = origin + t * dir;
        let g = self.field.sample(position).gradient;
        RayHit {
            t,
            position,
            normal: (-g).try_normalize().unwrap_or(-dir),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lone_particle_is_hit_on_its_iso_sphere() {
        let h = 0.1;
        let field = ColourField::with_volumes(&[Vec3::ZERO], &[0.5e-3], h).unwrap();
        let radius = field
            .lone_iso_radius(0.5e-3, 0.5)
            .expect("iso-sphere exists");
        let caster = Raycaster::new(&field, 0.5, h / 8.0);
        let origin = Vec3::new(0.02, 0.01, 1.0);
        let hit = caster.cast(origin, -Vec3::Z).expect("hits");
        let expected_z = (radius * radius - 0.02f32.powi(2) - 0.01f32.powi(2)).sqrt();
        assert!(
            (hit.position.z - expected_z).abs() < 1e-5,
            "{hit:?} vs z = {expected_z}"
        );
        assert!((hit.normal - hit.position.normalize()).length() < 1e-4);
        assert!(caster.cast(origin, Vec3::Z).is_none(), "pointing away");
        assert!(
            caster.cast(Vec3::new(1.0, 0.0, 1.0), -Vec3::Z).is_none(),
            "passing beside"
        );
    }

    /// Far from the origin a step of h/1000 is below the f32 resolution of
    /// the ray parameter: the march still ends, and finds the sphere.
    #[test]
    fn marching_ends_where_steps_are_below_f32_resolution() {
        let h = 0.04;
        let centre = Vec3::new(0.0, 0.0, -2e3);
        let field = ColourField::with_volumes(&[centre], &[0.5 * h * h * h], h).unwrap();
        let caster = Raycaster::new(&field, 0.5, 0.0);
        let coarse = Raycaster::new(&field, 0.5, h / 8.0);
        // t ≈ 2 km: an f32 ulp of t is 1.2e-4 m, above h/1000 = 4e-5 m.
        let fine = Raycaster {
            step: h * 1e-3,
            ..coarse
        };
        assert!(caster.cast(Vec3::ZERO, -Vec3::Z).is_some());
        let hit = fine.cast(Vec3::ZERO, -Vec3::Z).expect("hits");
        assert!((hit.position - centre).length() < h, "{hit:?}");
        assert!(fine.cast(Vec3::new(1.0, 0.0, 0.0), -Vec3::Z).is_none());
    }
}
