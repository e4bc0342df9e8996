//! The window's orbit camera: drag to rotate, scroll to zoom, right-drag to pan.

use glam::{Vec2, Vec3};
use splat_render::Camera;

/// A camera orbiting `target` at `distance`, `yaw` around +y, `pitch` above the horizon.
#[derive(Debug, Clone, Copy)]
pub struct Orbit {
    /// Point orbited.
    pub target: Vec3,
    /// Distance from the target (m).
    pub distance: f32,
    /// Rotation about +y (rad).
    pub yaw: f32,
    /// Elevation (rad); [`Orbit::rotate`] keeps it inside ±85°.
    pub pitch: f32,
    /// Vertical field of view (rad).
    pub fov_y: f32,
}

impl Orbit {
    /// The orbit through `camera`'s eye around its target.
    pub fn from_camera(camera: &Camera) -> Self {
        let d = camera.eye - camera.target;
        let distance = d.length().max(1e-3);
        Self {
            target: camera.target,
            distance,
            yaw: d.x.atan2(d.z),
            pitch: (d.y / distance).clamp(-1.0, 1.0).asin(),
            fov_y: camera.fov_y,
        }
    }

    /// The camera for this orbit.
    pub fn camera(&self) -> Camera {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        let eye = self.target + self.distance * Vec3::new(sy * cp, sp, cy * cp);
        Camera {
            fov_y: self.fov_y,
            ..Camera::looking_at(eye, self.target)
        }
        .with_planes_for_distance()
    }

    /// Rotates by a mouse drag of `delta` pixels.
    pub fn rotate(&mut self, delta: Vec2) {
        self.yaw -= delta.x * 0.008;
        self.pitch = (self.pitch + delta.y * 0.008).clamp(-1.48, 1.48);
    }

    /// Zooms by scroll `lines` (positive: closer).
    pub fn zoom(&mut self, lines: f32) {
        self.distance = (self.distance * 0.9f32.powf(lines)).clamp(1e-3, 1e4);
    }

    /// The world-space directions of screen right and up.
    pub fn screen_axes(&self) -> (Vec3, Vec3) {
        let c = self.camera();
        let forward = (c.target - c.eye).normalize();
        let right = forward.cross(Vec3::Y).normalize();
        (right, right.cross(forward))
    }

    /// Pans by a mouse drag of `delta` pixels in a window `height` pixels tall.
    pub fn pan(&mut self, delta: Vec2, height: f32) {
        let (right, up) = self.screen_axes();
        let scale = 2.0 * self.distance * (self.fov_y / 2.0).tan() / height.max(1.0);
        self.target += (-delta.x * right + delta.y * up) * scale;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orbit_reproduces_the_camera_it_came_from() {
        let cam = Camera::looking_at(Vec3::new(0.3, 0.6, 1.5), Vec3::new(0.5, 0.1, 0.0));
        let back = Orbit::from_camera(&cam).camera();
        assert!(
            (back.eye - cam.eye).length() < 1e-5,
            "{} vs {}",
            back.eye,
            cam.eye
        );
        assert_eq!(back.target, cam.target);
    }
}
