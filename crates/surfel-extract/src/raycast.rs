//! A reference ray caster of the iso-surface c(x) = k_iso: what the surfels
//! approximate, found without surfels. Renderers compare their images with it
//! (silhouette, normals, shading).

use glam::Vec3;
use sph_core::{Error, Result};

use crate::field::ColourField;

/// The most steps a ray may take across the field's support box: a
/// [`Raycaster`] whose step would need more is refused rather than left to
/// march for minutes (two particles 3 km apart at h/8 = 5 mm would take
/// 10⁶ per ray).
pub const MAX_RAY_STEPS: f32 = 1e6;

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
    /// A ray caster for `field` at `iso` marching in steps of `step` (m).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming `iso` outside (0, 1)
    /// ([`crate::check_iso`]), or `step` outside [h/1000, h] or so short
    /// that a ray across the field's support box would take more than
    /// [`MAX_RAY_STEPS`].
    pub fn new(field: &'a ColourField, iso: f32, step: f32) -> Result<Self> {
        crate::check_iso(iso)?;
        let h = field.h();
        if !(step.is_finite() && step >= h * 1e-3 && step <= h) {
            return Err(Error::InvalidParameter {
                name: "step",
                value: step.to_string(),
                reason: "must lie in [h/1000, h] (h/8 resolves every feature the poly6 field can form)",
            });
        }
        let bounds = field.support_bounds();
        let width = bounds.map_or(0.0, |(lo, hi)| (hi - lo).length());
        if width / step > MAX_RAY_STEPS {
            return Err(Error::InvalidParameter {
                name: "step",
                value: format!("{step} m across a support box {width} m wide"),
                reason: "would take more than 10^6 steps per ray: take a longer step, or \
                         cast against the particles near the view only",
            });
        }
        Ok(Self {
            field,
            iso,
            step,
            bounds,
        })
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
        let caster = Raycaster::new(&field, 0.5, h / 8.0).unwrap();
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
        let coarse = Raycaster::new(&field, 0.5, h / 8.0).unwrap();
        // t ≈ 2 km: an f32 ulp of t is 1.2e-4 m, above h/1000 = 4e-5 m.
        let fine = Raycaster::new(&field, 0.5, h * 1e-3).unwrap();
        assert!(coarse.cast(Vec3::ZERO, -Vec3::Z).is_some());
        let hit = fine.cast(Vec3::ZERO, -Vec3::Z).expect("hits");
        assert!((hit.position - centre).length() < h, "{hit:?}");
        assert!(fine.cast(Vec3::new(1.0, 0.0, 0.0), -Vec3::Z).is_none());
    }

    /// Bad settings are errors naming them, not clamped: an iso outside
    /// (0, 1), a step outside [h/1000, h], and a step that would march a
    /// ray across a support box 1 km wide (two particles far apart) 10⁷
    /// times.
    #[test]
    fn bad_settings_are_refused() {
        let h = 0.01;
        let near = ColourField::with_volumes(&[Vec3::ZERO], &[h * h * h], h).unwrap();
        let name = |r: Result<Raycaster<'_>>| match r {
            Err(Error::InvalidParameter { name, .. }) => name,
            other => panic!("{other:?}"),
        };
        for iso in [0.0, -1.0, 1.0, f32::NAN] {
            assert_eq!(name(Raycaster::new(&near, iso, h / 8.0)), "iso");
        }
        for step in [0.0, h * 1e-4, 2.0 * h, f32::NAN, f32::INFINITY] {
            assert_eq!(name(Raycaster::new(&near, 0.5, step)), "step");
        }
        let far = [Vec3::splat(-300.0), Vec3::splat(300.0)];
        let far = ColourField::with_volumes(&far, &[h * h * h; 2], h).unwrap();
        assert_eq!(name(Raycaster::new(&far, 0.5, h / 100.0)), "step");
        assert!(Raycaster::new(&far, 0.5, h).is_ok(), "1.04e5 steps a ray");
    }
}
