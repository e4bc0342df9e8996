//! Opaque scene geometry drawn around the fluid: boxes, spheres, an open
//! container and a ground plane, lit by the environment. The splats are
//! depth-tested against it and the refraction samples it, so the water sits
//! in its tank and bends what is actually behind it.
//!
//! The crate still knows nothing of SPH: a caller (the demo) turns its
//! scene's walls and obstacles into [`Object`]s.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use crate::error::{RenderError, Result};

/// The direction towards the sun of the procedural environment
/// ([`procedural_environment`](crate::textures::procedural_environment)).
pub const SUN: Vec3 = Vec3::new(0.4, 0.6, -0.7);

/// A triangle mesh with per-vertex normals; counter-clockwise triangles
/// (seen from where the normal points) are its front faces, and only front
/// faces are drawn.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    indices: Vec<u32>,
}

impl Mesh {
    /// A closed box between `min` and `max`, its faces seen from outside.
    ///
    /// # Errors
    /// [`RenderError::InvalidGeometry`] unless both corners are finite and
    /// `min < max` on every axis.
    pub fn cuboid(min: Vec3, max: Vec3) -> Result<Self> {
        check_box("cuboid", min, max)?;
        let mut mesh = Self::default();
        for face in FACES {
            mesh.face(min, max, face, false);
        }
        Ok(mesh)
    }

    /// An open-topped tank between `min` and `max`: its floor and four walls
    /// seen from *inside*. Drawn with back faces culled, the walls between
    /// the camera and the fluid vanish wherever the camera stands outside,
    /// and the floor and far walls frame the water (a cutaway).
    ///
    /// # Errors
    /// As [`Mesh::cuboid`].
    pub fn container(min: Vec3, max: Vec3) -> Result<Self> {
        check_box("container", min, max)?;
        let mut mesh = Self::default();
        // Every face but the top (+y).
        for face in FACES.into_iter().filter(|f| f.normal != Vec3::Y) {
            mesh.face(min, max, face, true);
        }
        Ok(mesh)
    }

    /// A UV sphere of `segments` slices around +y (and half as many stacks),
    /// seen from outside; 32 segments look round at demo sizes.
    ///
    /// # Errors
    /// [`RenderError::InvalidGeometry`] for a non-finite centre, a radius
    /// that is not finite and > 0, or fewer than 3 segments.
    pub fn sphere(centre: Vec3, radius: f32, segments: u32) -> Result<Self> {
        if !(centre.is_finite() && radius.is_finite() && radius > 0.0) {
            return Err(RenderError::InvalidGeometry(format!(
                "sphere: centre {centre} and radius {radius} must be finite, the radius > 0"
            )));
        }
        if !(3..=1024).contains(&segments) {
            return Err(RenderError::InvalidGeometry(format!(
                "sphere: {segments} segments (3 to 1024)"
            )));
        }
        let stacks = (segments / 2).max(2);
        let mut mesh = Self::default();
        for i in 0..=stacks {
            let theta = std::f32::consts::PI * i as f32 / stacks as f32;
            for j in 0..=segments {
                let phi = std::f32::consts::TAU * j as f32 / segments as f32;
                let n = Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    -theta.sin() * phi.sin(),
                );
                mesh.positions.push(centre + radius * n);
                mesh.normals.push(n);
            }
        }
        let row = segments + 1;
        for i in 0..stacks {
            for j in 0..segments {
                let (a, b) = (i * row + j, (i + 1) * row + j);
                mesh.indices.extend([a, b, a + 1, a + 1, b, b + 1]);
            }
        }
        Ok(mesh)
    }

    /// A square of half-side `half` at height `y` centred over `centre`'s x
    /// and z, facing up: the ground the scene stands on.
    ///
    /// # Errors
    /// [`RenderError::InvalidGeometry`] for non-finite values or `half ≤ 0`.
    pub fn ground(centre: Vec3, y: f32, half: f32) -> Result<Self> {
        if !(centre.is_finite() && y.is_finite() && half.is_finite() && half > 0.0) {
            return Err(RenderError::InvalidGeometry(format!(
                "ground: centre {centre}, height {y} and half-side {half} must be finite, the half-side > 0"
            )));
        }
        let c = Vec3::new(centre.x, y, centre.z);
        let min = c - Vec3::new(half, 0.0, half);
        let max = c + Vec3::new(half, 0.0, half);
        let mut mesh = Self::default();
        mesh.face(min, max, FACES[2], false);
        Ok(mesh)
    }

    /// Vertex positions.
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Triangle list indices into [`Mesh::positions`].
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }

    /// Appends the quad of `face` of the box (min, max), its normal
    /// flipped inwards when `inside`.
    fn face(&mut self, min: Vec3, max: Vec3, face: Face, inside: bool) {
        let corner = |s: [f32; 3]| {
            Vec3::new(
                if s[0] > 0.0 { max.x } else { min.x },
                if s[1] > 0.0 { max.y } else { min.y },
                if s[2] > 0.0 { max.z } else { min.z },
            )
        };
        let base = self.positions.len() as u32;
        let n = if inside { -face.normal } else { face.normal };
        for c in face.corners {
            self.positions.push(corner(c));
            self.normals.push(n);
        }
        let quad = if inside {
            [0, 2, 1, 0, 3, 2]
        } else {
            [0, 1, 2, 0, 2, 3]
        };
        self.indices.extend(quad.map(|k| base + k));
    }
}

/// One box face: its outward normal and its corners (as signs per axis),
/// counter-clockwise seen from outside.
#[derive(Clone, Copy)]
struct Face {
    normal: Vec3,
    corners: [[f32; 3]; 4],
}

const FACES: [Face; 6] = [
    Face {
        normal: Vec3::X,
        corners: [[1., -1., 1.], [1., -1., -1.], [1., 1., -1.], [1., 1., 1.]],
    },
    Face {
        normal: Vec3::NEG_X,
        corners: [
            [-1., -1., -1.],
            [-1., -1., 1.],
            [-1., 1., 1.],
            [-1., 1., -1.],
        ],
    },
    Face {
        normal: Vec3::Y,
        corners: [[-1., 1., 1.], [1., 1., 1.], [1., 1., -1.], [-1., 1., -1.]],
    },
    Face {
        normal: Vec3::NEG_Y,
        corners: [
            [-1., -1., -1.],
            [1., -1., -1.],
            [1., -1., 1.],
            [-1., -1., 1.],
        ],
    },
    Face {
        normal: Vec3::Z,
        corners: [[-1., -1., 1.], [1., -1., 1.], [1., 1., 1.], [-1., 1., 1.]],
    },
    Face {
        normal: Vec3::NEG_Z,
        corners: [
            [1., -1., -1.],
            [-1., -1., -1.],
            [-1., 1., -1.],
            [1., 1., -1.],
        ],
    },
];

fn check_box(what: &str, min: Vec3, max: Vec3) -> Result<()> {
    if !(min.is_finite() && max.is_finite() && min.cmplt(max).all()) {
        return Err(RenderError::InvalidGeometry(format!(
            "{what}: corners {min} and {max} must be finite with min < max on every axis"
        )));
    }
    Ok(())
}

/// How an [`Object`] looks: a diffuse colour lit by the environment, with
/// optional grid lines (tiles) that show scale and how the water bends them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Diffuse reflectance per channel, 0..1.
    pub colour: Vec3,
    /// Spacing of dark grid lines in world units along the surface's two
    /// in-plane axes; 0 draws none.
    pub grid: f32,
}

impl Material {
    /// A plain colour.
    pub fn plain(colour: Vec3) -> Self {
        Self { colour, grid: 0.0 }
    }

    /// A colour with grid lines every `grid` world units.
    pub fn tiled(colour: Vec3, grid: f32) -> Self {
        Self { colour, grid }
    }
}

/// A mesh and its material.
#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    /// The triangles.
    pub mesh: Mesh,
    /// How they look.
    pub material: Material,
}

/// What fills the pixels that no object covers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Backdrop {
    /// The environment's screen-space background image stretched over the
    /// viewport (the thesis's t_back).
    #[default]
    Screen,
    /// The environment map seen along each pixel's view ray: the same sky
    /// the fluid reflects.
    Environment,
}

/// Everything drawn besides the fluid.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneGeometry {
    /// Opaque objects.
    pub objects: Vec<Object>,
    /// Behind the objects.
    pub backdrop: Backdrop,
    /// Direction towards the sun that lights the objects (normalised on
    /// upload); [`SUN`] matches the procedural environment.
    pub sun: Vec3,
}

impl Default for SceneGeometry {
    /// No objects in front of the screen-space background: the thesis's picture.
    fn default() -> Self {
        Self {
            objects: Vec::new(),
            backdrop: Backdrop::Screen,
            sun: SUN,
        }
    }
}

/// GPU vertex: position and grid spacing, normal, colour.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct GpuVertex {
    pub position_grid: [f32; 4],
    pub normal: [f32; 4],
    pub colour: [f32; 4],
}

impl SceneGeometry {
    /// Validates and flattens the objects into one vertex and index list.
    pub(crate) fn flatten(&self) -> Result<(Vec<GpuVertex>, Vec<u32>)> {
        if !(self.sun.is_finite() && self.sun.length_squared() > 0.0) {
            return Err(RenderError::InvalidGeometry(format!(
                "sun direction {} must be finite and non-zero",
                self.sun
            )));
        }
        let (mut vertices, mut indices) = (Vec::new(), Vec::new());
        for (k, object) in self.objects.iter().enumerate() {
            let Material { colour, grid } = object.material;
            if !(colour.is_finite() && colour.cmpge(Vec3::ZERO).all()) {
                return Err(RenderError::InvalidGeometry(format!(
                    "object {k}: colour {colour} must be finite and >= 0"
                )));
            }
            if !(grid.is_finite() && grid >= 0.0) {
                return Err(RenderError::InvalidGeometry(format!(
                    "object {k}: grid spacing {grid} must be finite and >= 0"
                )));
            }
            let mesh = &object.mesh;
            if mesh.positions.iter().any(|p| !p.is_finite()) {
                return Err(RenderError::InvalidGeometry(format!(
                    "object {k}: a vertex position is not finite"
                )));
            }
            let base = u32::try_from(vertices.len())
                .map_err(|_| RenderError::InvalidGeometry("more than 2³² vertices".into()))?;
            indices.extend(mesh.indices.iter().map(|&i| base + i));
            vertices.extend(
                mesh.positions
                    .iter()
                    .zip(&mesh.normals)
                    .map(|(p, n)| GpuVertex {
                        position_grid: p.extend(grid).to_array(),
                        normal: n.extend(0.0).to_array(),
                        colour: colour.extend(1.0).to_array(),
                    }),
            );
        }
        Ok((vertices, indices))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each triangle's winding agrees with its vertices' normal (front faces
    /// counter-clockwise seen from where the normal points).
    fn assert_wound(mesh: &Mesh) {
        for t in mesh.indices.chunks(3) {
            let [a, b, c] = [0, 1, 2].map(|k| t[k] as usize);
            let (pa, pb, pc) = (mesh.positions[a], mesh.positions[b], mesh.positions[c]);
            let face = (pb - pa).cross(pc - pa);
            if face.length() < 1e-6 * (pb - pa).length_squared().max((pc - pa).length_squared()) {
                continue; // a sphere's pole
            }
            let n = mesh.normals[a] + mesh.normals[b] + mesh.normals[c];
            assert!(
                face.dot(n) > 0.0,
                "triangle {t:?} is wound against its normal"
            );
        }
    }

    #[test]
    fn boxes_spheres_and_grounds_are_wound_with_their_normals() {
        let (min, max) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.5, 0.25));
        let cube = Mesh::cuboid(min, max).unwrap();
        assert_eq!((cube.positions.len(), cube.indices.len()), (24, 36));
        assert_wound(&cube);
        let tank = Mesh::container(min, max).unwrap();
        assert_eq!(tank.indices.len(), 30, "five faces, no lid");
        assert_wound(&tank);
        // Inside: every normal points towards the box's centre.
        let centre = 0.5 * (min + max);
        for (p, n) in tank.positions.iter().zip(&tank.normals) {
            assert!((centre - *p).dot(*n) > 0.0);
        }
        let ball = Mesh::sphere(Vec3::ONE, 0.5, 16).unwrap();
        assert_wound(&ball);
        for p in &ball.positions {
            assert!(((*p - Vec3::ONE).length() - 0.5).abs() < 1e-6);
        }
        let ground = Mesh::ground(Vec3::new(1.0, 5.0, 2.0), -0.1, 3.0).unwrap();
        assert_wound(&ground);
        assert!(ground.normals.iter().all(|n| *n == Vec3::Y));
        assert!(ground.positions.iter().all(|p| p.y == -0.1));
    }

    #[test]
    fn bad_geometry_is_an_error_naming_what() {
        let e = |r: Result<Mesh>| r.unwrap_err().to_string();
        assert!(e(Mesh::cuboid(Vec3::ONE, Vec3::ZERO)).contains("cuboid"));
        assert!(
            e(Mesh::container(Vec3::ZERO, Vec3::new(1.0, f32::NAN, 1.0))).contains("container")
        );
        assert!(e(Mesh::sphere(Vec3::ZERO, -1.0, 16)).contains("radius"));
        assert!(e(Mesh::sphere(Vec3::ZERO, 1.0, 2)).contains("segments"));
        assert!(e(Mesh::ground(Vec3::ZERO, 0.0, 0.0)).contains("ground"));
        let object = |material| Object {
            mesh: Mesh::cuboid(Vec3::ZERO, Vec3::ONE).unwrap(),
            material,
        };
        let bad = [
            (Material::plain(Vec3::new(0.5, f32::NAN, 0.5)), "colour"),
            (Material::plain(Vec3::new(0.5, -0.1, 0.5)), "colour"),
            (Material::tiled(Vec3::ONE, f32::INFINITY), "grid"),
            (Material::tiled(Vec3::ONE, -0.1), "grid"),
        ];
        for (material, field) in bad {
            let scene = SceneGeometry {
                objects: vec![object(material)],
                ..Default::default()
            };
            let err = scene.flatten().unwrap_err().to_string();
            assert!(err.contains(field) && err.contains("object 0"), "{err}");
        }
        let scene = SceneGeometry {
            sun: Vec3::ZERO,
            ..Default::default()
        };
        assert!(scene.flatten().unwrap_err().to_string().contains("sun"));
    }

    #[test]
    fn objects_flatten_into_one_indexed_list() {
        let scene = SceneGeometry {
            objects: vec![
                Object {
                    mesh: Mesh::cuboid(Vec3::ZERO, Vec3::ONE).unwrap(),
                    material: Material::plain(Vec3::ONE),
                },
                Object {
                    mesh: Mesh::ground(Vec3::ZERO, 0.0, 1.0).unwrap(),
                    material: Material::tiled(Vec3::splat(0.5), 0.1),
                },
            ],
            ..Default::default()
        };
        let (v, i) = scene.flatten().unwrap();
        assert_eq!((v.len(), i.len()), (28, 42));
        assert!(i[36..].iter().all(|&k| (24..28).contains(&k)));
        assert_eq!(v[24].position_grid[3], 0.1);
    }
}
