//! What the demo draws around the fluid: the scene's tank (an open-topped
//! cutaway container), its obstacles and the ground, before the
//! environment's sky. The renderer knows nothing of SPH; this is where a
//! [`Scene`]'s walls and obstacles become [`SceneGeometry`].

use glam::Vec3;
use sph_core::Scene;
use sph_core::scene::ObstacleSpec;
use splat_render::{Backdrop, Material, Mesh, Object, SceneGeometry};

use crate::error::AppError;

/// The tank's floor and walls: light stone with 10 cm tiles.
const TANK: Vec3 = Vec3::new(0.80, 0.78, 0.74);
/// Obstacles: terracotta, to stand out against the water.
const OBSTACLE: Vec3 = Vec3::new(0.85, 0.42, 0.22);
/// The ground around the tank.
const GROUND: Vec3 = Vec3::new(0.62, 0.60, 0.55);

/// The geometry of `scene`: its domain as a container seen from outside
/// (the walls between the camera and the fluid are not drawn), the
/// obstacles, and a ground plane under it all, before the environment
/// map's sky.
///
/// # Errors
/// [`AppError::Render`] for a degenerate domain or obstacle (the scene's own
/// validation rejects those first).
pub fn scenery(scene: &Scene) -> Result<SceneGeometry, AppError> {
    let (min, max) = (Vec3::from(scene.domain.min), Vec3::from(scene.domain.max));
    let grid = tile_size((max - min).max_element());
    let mut geometry = ground(scene)?;
    geometry.objects.insert(
        0,
        Object {
            mesh: Mesh::container(min, max)?,
            material: Material::tiled(TANK, grid),
        },
    );
    for obstacle in &scene.obstacles {
        let mesh = match *obstacle {
            ObstacleSpec::Box { min, max } => Mesh::cuboid(min.into(), max.into())?,
            ObstacleSpec::Sphere { centre, radius } => Mesh::sphere(centre.into(), radius, 48)?,
        };
        geometry.objects.push(Object {
            mesh,
            material: Material::plain(OBSTACLE),
        });
    }
    Ok(geometry)
}

/// The ground plane under `scene`'s domain alone, before the environment
/// map's sky: what a playback of other simulators' particles stands on.
///
/// # Errors
/// [`AppError::Render`] for a degenerate domain.
pub fn ground(scene: &Scene) -> Result<SceneGeometry, AppError> {
    let (min, max) = (Vec3::from(scene.domain.min), Vec3::from(scene.domain.max));
    let extent = (max - min).max_element();
    let grid = tile_size(extent);
    let objects = vec![
        // Just below the domain's floor, so that it and a tank never fight
        // for a pixel.
        Object {
            mesh: Mesh::ground(0.5 * (min + max), min.y - 1e-3 * extent, 6.0 * extent)?,
            material: Material::tiled(GROUND, 5.0 * grid),
        },
    ];
    Ok(SceneGeometry {
        objects,
        backdrop: Backdrop::Environment,
        ..Default::default()
    })
}

/// A round tile size, about a tenth of `extent`: 1, 2 or 5 times a power of ten.
fn tile_size(extent: f32) -> f32 {
    let rough = (0.1 * extent).max(f32::MIN_POSITIVE);
    let decade = 10f32.powf(rough.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .find(|&s| s * decade >= rough * 0.75)
        .unwrap_or(10.0);
    step * decade
}

#[cfg(test)]
mod tests {
    use image::RgbaImage;
    use splat_render::{GpuContext, SplatRenderer};

    use super::*;
    use crate::pipeline::Pipeline;

    /// `name` after `frames` 60 Hz frames, drawn at 480×270 by the demo's
    /// camera and shading, with or without its scenery; also the pixels
    /// the fluid covers.
    fn frame(ctx: &GpuContext, name: &str, frames: u32, with_scenery: bool) -> (RgbaImage, usize) {
        let (name, scene) = crate::scenes::resolve(name).unwrap();
        let mut pipeline = Pipeline::new(name, scene, 2).unwrap();
        for _ in 0..frames {
            pipeline.advance(1.0 / 60.0).unwrap();
        }
        pipeline.extract_surfels().unwrap();
        let mut renderer = SplatRenderer::new(ctx, 480, 270, &crate::environment()).unwrap();
        if with_scenery {
            renderer
                .set_geometry(ctx, &pipeline.scenery().unwrap())
                .unwrap();
        }
        pipeline.show_surfels(ctx, &mut renderer).unwrap();
        let (camera, shading) = (pipeline.camera(), pipeline.shading());
        renderer.render(ctx, &camera, &shading).unwrap();
        let covered = renderer.read_accumulation(ctx).unwrap();
        let covered = (0..270)
            .flat_map(|y| (0..480).map(move |x| (x, y)))
            .filter(|&(x, y)| covered.weight(x, y) > 0.0)
            .count();
        (renderer.read_image(ctx).unwrap(), covered)
    }

    /// Reddish: the obstacles' terracotta, lit, maybe seen through water
    /// (which absorbs red most); nothing else in the picture is.
    fn reddish(p: &image::Rgba<u8>) -> bool {
        let [r, g, b, _] = p.0.map(u32::from);
        r > g + 15 && r > b + 30
    }

    /// The dam break in its tank and the 3D dam break with its sphere and
    /// wall, against goldens (`tests/golden/scenery-*.png`, FLIP mean ≤
    /// 0.002 against a measured 0.0000–0.0002; `SPH_UPDATE_GOLDEN=1`
    /// rewrites them). The obstacles show, and the geometry hides fluid
    /// behind it.
    #[test]
    fn the_tank_and_obstacles_render_as_their_goldens() {
        let Some(ctx) = GpuContext::headless_or_skip() else {
            return;
        };
        for (name, obstacles) in [("dam-break", false), ("dam-break-3d", true)] {
            let (image, covered) = frame(ctx, name, 30, true);
            let (bare_image, bare) = frame(ctx, name, 30, false);
            let orange = image.pixels().filter(|p| reddish(p)).count();
            let bare_orange = bare_image.pixels().filter(|p| reddish(p)).count();
            println!(
                "{name}: {covered} px of fluid ({bare} without the scenery), \
                 {orange} px of obstacle ({bare_orange} without)"
            );
            assert!(
                bare_orange < 20,
                "{name}: {bare_orange} reddish px without obstacles"
            );
            if obstacles {
                assert!(orange > 1_000, "{name}: the obstacles show in {orange} px");
                assert!(covered < bare, "{name}: the sphere and wall hide no fluid");
            } else {
                assert!(orange < 50, "{name}: {orange} px of obstacle colour");
            }
            let mean = crate::golden::against(&format!("scenery-{name}"), &image, 0.002);
            println!("{name}: FLIP mean vs golden {mean:.4}");
            assert!(mean <= 0.002, "{name}: FLIP mean {mean} against its golden");
        }
    }

    #[test]
    fn tiles_are_round_tenths() {
        assert_eq!(tile_size(1.0), 0.1);
        assert!((tile_size(0.6) - 0.05).abs() < 1e-6);
        assert!((tile_size(2.5) - 0.2).abs() < 1e-6);
    }

    #[test]
    fn every_built_in_scene_has_its_tank_ground_and_obstacles() {
        for (name, _, make) in crate::scenes::BUILT_IN {
            let scene = make();
            let geometry = scenery(&scene).unwrap();
            assert_eq!(
                geometry.objects.len(),
                2 + scene.obstacles.len(),
                "{name}: tank, ground and obstacles"
            );
            assert_eq!(geometry.backdrop, Backdrop::Environment);
        }
    }
}
