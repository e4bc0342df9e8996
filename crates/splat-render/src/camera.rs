//! [`Camera`]: a perspective pinhole camera (right-handed, +y up, depth 0..1).

use glam::{Mat4, Vec2, Vec3};

use crate::error::{RenderError, Result};

/// A perspective camera looking from `eye` at `target`.
///
/// Pixel `(x, y)` has its centre at `(x + 0.5, y + 0.5)`, with `y` growing
/// downwards, as in wgpu's framebuffer coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position (world space).
    pub eye: Vec3,
    /// Point looked at.
    pub target: Vec3,
    /// Up direction (need not be orthogonal to the view direction).
    pub up: Vec3,
    /// Vertical field of view in radians.
    pub fov_y: f32,
    /// Near clip distance (> 0).
    pub near: f32,
    /// Far clip distance (> near).
    pub far: f32,
}

impl Camera {
    /// A camera at `eye` looking at `target`, +y up, 45° vertical field of view,
    /// clip planes 0.01 and 100.
    pub fn looking_at(eye: Vec3, target: Vec3) -> Self {
        Self {
            eye,
            target,
            up: Vec3::Y,
            fov_y: 45f32.to_radians(),
            near: 0.01,
            far: 100.0,
        }
    }

    /// This camera with clip planes scaled to its distance d from the
    /// target: d/100 and 100 d, so a scene's camera 300 m out or a tank in
    /// millimetres is drawn as one 1 m out is (the fixed planes of
    /// [`Camera::looking_at`] clip beyond 100 m), with the same depth
    /// precision. Beyond about 3e36 m the far plane overflows f32, which
    /// [`Camera::validate`] reports.
    pub fn with_planes_for_distance(self) -> Self {
        // Scaled first: |v|² of a vector 1e20 long overflows f32.
        let v = self.eye - self.target;
        let largest = v.abs().max_element();
        let distance = if largest > 0.0 {
            largest * (v / largest).length()
        } else {
            0.0 // eye on target: validation names that
        };
        Self {
            near: distance * 0.01,
            far: distance * 100.0,
            ..self
        }
    }

    /// Checks that the camera can be projected.
    ///
    /// # Errors
    /// [`RenderError::InvalidCamera`] for non-finite values, an eye on the
    /// target or so far from it that their difference overflows f32, an up
    /// vector that is zero or along the view direction, a field of view
    /// outside (0, π) or so near either end that the projection's focal
    /// length 1/tan(fov_y/2) leaves [10⁻⁴, 10⁴] (narrower than 0.011°,
    /// wider than 179.989°: a blank image), or clip planes with `0 < near <
    /// far` violated.
    pub fn validate(&self) -> Result<()> {
        let finite = self.eye.is_finite()
            && self.target.is_finite()
            && self.up.is_finite()
            && self.fov_y.is_finite()
            && self.near.is_finite()
            && self.far.is_finite();
        if !finite {
            return Err(RenderError::InvalidCamera("a field is not finite"));
        }
        let forward = self.target - self.eye;
        if forward == Vec3::ZERO {
            return Err(RenderError::InvalidCamera("eye and target coincide"));
        }
        if !forward.is_finite() {
            return Err(RenderError::InvalidCamera(
                "eye and target are so far apart that their difference overflows f32",
            ));
        }
        // Directions scaled to their largest component first, so that
        // neither a tiny nor a huge vector under- or overflows.
        let unit = |v: Vec3| (v / v.abs().max_element()).normalize();
        if self.up == Vec3::ZERO || unit(forward).cross(unit(self.up)).length_squared() < 1e-12 {
            return Err(RenderError::InvalidCamera(
                "up is zero or parallel to the view direction",
            ));
        }
        if !(self.fov_y > 0.0 && self.fov_y < std::f32::consts::PI) {
            return Err(RenderError::InvalidCamera("fov_y must lie in (0, π)"));
        }
        let focal = 1.0 / (0.5 * self.fov_y).tan();
        if !(1e-4..=1e4).contains(&focal) {
            return Err(RenderError::InvalidCamera(
                "fov_y is within 0.011° of 0 or 180°: the projection draws nothing",
            ));
        }
        if !(self.near > 0.0 && self.far > self.near) {
            return Err(RenderError::InvalidCamera("need 0 < near < far"));
        }
        Ok(())
    }

    /// World → view transform (camera at the origin looking down −z).
    pub fn view(&self) -> Mat4 {
        glam::camera::rh::view::look_at_mat4(self.eye, self.target, self.up)
    }

    /// View → clip projection for a `width`×`height` image (depth maps to 0..1).
    pub fn projection(&self, width: u32, height: u32) -> Mat4 {
        let aspect = width.max(1) as f32 / height.max(1) as f32;
        // wgpu clip space: right-handed view, NDC y up, depth 0..1 (the "directx" convention).
        glam::camera::rh::proj::directx::perspective(self.fov_y, aspect, self.near, self.far)
    }

    /// The view-space direction (z = −1) of the ray through pixel position
    /// `pixel` (pixel centres at half-integers), the same reconstruction the
    /// shaders use. A pixel outside the image gives the ray beyond the
    /// frustum's edge (a drag leaving the window); an empty image's size is
    /// taken as 1, as [`Camera::projection`] takes it, so the ray is finite.
    pub fn view_ray(&self, pixel: Vec2, width: u32, height: u32) -> Vec3 {
        let proj = self.projection(width, height);
        let ndc = Vec2::new(
            2.0 * pixel.x / width.max(1) as f32 - 1.0,
            1.0 - 2.0 * pixel.y / height.max(1) as f32,
        );
        Vec3::new(ndc.x / proj.x_axis.x, ndc.y / proj.y_axis.y, -1.0)
    }

    /// The world-space ray (origin, unit direction) through the centre of pixel `(x, y)`.
    pub fn pixel_ray(&self, x: u32, y: u32, width: u32, height: u32) -> (Vec3, Vec3) {
        let dir = self.view_ray(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), width, height);
        let world = self.view().inverse().transform_vector3(dir).normalize();
        (self.eye, world)
    }

    /// Where world point `p` lands in pixel coordinates, or `None` behind the eye.
    pub fn project(&self, p: Vec3, width: u32, height: u32) -> Option<Vec2> {
        let clip = self.projection(width, height) * self.view() * p.extend(1.0);
        (clip.w > 0.0).then(|| {
            let ndc = clip.truncate() / clip.w;
            Vec2::new(
                (ndc.x + 1.0) * 0.5 * width as f32,
                (1.0 - ndc.y) * 0.5 * height as f32,
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_empty_image_gives_a_finite_ray() {
        let cam = Camera::looking_at(Vec3::new(1.0, 2.0, 5.0), Vec3::ZERO);
        for (w, h) in [(0, 0), (0, 200), (320, 0)] {
            let (o, d) = cam.pixel_ray(0, 0, w, h);
            assert!(o.is_finite() && d.is_finite(), "{w}×{h}: {d}");
            assert!((d.length() - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn pixel_ray_hits_projected_point() {
        let cam = Camera::looking_at(Vec3::new(1.0, 2.0, 5.0), Vec3::new(0.2, 0.1, 0.0));
        let p = Vec3::new(0.5, 0.3, -0.4);
        let px = cam.project(p, 320, 200).unwrap();
        let (o, d) = cam.pixel_ray(px.x as u32, px.y as u32, 320, 200);
        // The ray through the pixel containing p passes within a pixel's footprint of p.
        let dist = (p - o).cross(d).length();
        let pixel_size = 2.0 * (cam.fov_y / 2.0).tan() * (p - o).length() / 200.0;
        assert!(dist < pixel_size, "{dist} vs {pixel_size}");
    }

    #[test]
    fn bad_cameras_are_rejected() {
        let ok = Camera::looking_at(Vec3::Z, Vec3::ZERO);
        assert!(ok.validate().is_ok());
        assert!(
            Camera {
                eye: Vec3::ZERO,
                ..ok
            }
            .validate()
            .is_err()
        );
        assert!(Camera { up: Vec3::Z, ..ok }.validate().is_err());
        assert!(Camera { near: 0.0, ..ok }.validate().is_err());
        assert!(
            Camera {
                fov_y: f32::NAN,
                ..ok
            }
            .validate()
            .is_err()
        );
        // Overflowing, zero or huge vectors and near-degenerate fields of
        // view, which passed before and drew blank or black frames.
        let far_apart = Camera::looking_at(Vec3::Z * 3e38, -Vec3::Z * 3e38);
        let huge_up = Camera {
            up: Vec3::Y * 1e30,
            ..ok
        };
        assert!(huge_up.validate().is_ok(), "only its direction counts");
        for (bad, what) in [
            (far_apart, "overflows"),
            (
                Camera {
                    up: Vec3::ZERO,
                    ..ok
                },
                "up is zero",
            ),
            (Camera { fov_y: 1e-40, ..ok }, "0.011°"),
            (
                Camera {
                    fov_y: std::f32::consts::PI * (1.0 - 1e-7),
                    ..ok
                },
                "0.011°",
            ),
        ] {
            match bad.validate() {
                Err(RenderError::InvalidCamera(m)) => assert!(m.contains(what), "{m}"),
                other => panic!("{bad:?}: {other:?}"),
            }
        }
        // A camera a micrometre from its target still gets clip planes.
        let close = Camera::looking_at(Vec3::Z * 1e-6, Vec3::ZERO).with_planes_for_distance();
        assert!(close.validate().is_ok(), "{close:?}");
        let on = Camera::looking_at(Vec3::ZERO, Vec3::ZERO).with_planes_for_distance();
        match on.validate() {
            Err(RenderError::InvalidCamera(m)) => assert!(m.contains("coincide"), "{m}"),
            other => panic!("{other:?}"),
        }
        // And one 1e20 m out is not called vertical.
        let distant = Camera::looking_at(Vec3::Z * 1e20, Vec3::ZERO).with_planes_for_distance();
        assert!(distant.validate().is_ok(), "{distant:?}");
    }
}
