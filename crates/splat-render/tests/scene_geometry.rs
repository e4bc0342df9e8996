//! Scene geometry around the splats (lavapipe in CI): opaque objects hide
//! the splats behind them, the refraction shows the geometry behind the
//! fluid, and Beer–Lambert absorption colours deep fluid more than a thin
//! sheet, by the measured amounts. Without an adapter these print "skipped:
//! no GPU adapter" and pass, unless `SPH_REQUIRE_GPU=1`.

use glam::{Vec2, Vec3};
use image::{Rgba, RgbaImage};
use splat_render::shading::transmittance;
use splat_render::{
    Backdrop, Camera, Environment, GpuContext, Material, Mesh, Object, SceneGeometry, Shading,
    Splat, SplatPath, SplatRenderer, View,
};

const W: u32 = 160;
const H: u32 = 120;

fn camera() -> Camera {
    Camera::looking_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO)
}

/// The pixel `p` projects to.
fn pixel(p: Vec3) -> (u32, u32) {
    let q: Vec2 = camera().project(p, W, H).expect("in view");
    (q.x as u32, q.y as u32)
}

/// A uniform grey backdrop, so that what the fluid passes is known exactly.
fn grey_environment(level: u8) -> Environment {
    Environment {
        background: RgbaImage::from_pixel(4, 4, Rgba([level, level, level, 255])),
        ..Environment::procedural()
    }
}

fn box_object(min: Vec3, max: Vec3, colour: Vec3) -> Object {
    Object {
        mesh: Mesh::cuboid(min, max).unwrap(),
        material: Material::plain(colour),
    }
}

fn renderer(ctx: &GpuContext, env: &Environment, geometry: &SceneGeometry) -> SplatRenderer {
    let mut r = SplatRenderer::new(ctx, W, H, env).unwrap();
    r.set_splat_path(ctx, SplatPath::Raster).unwrap();
    r.set_geometry(ctx, geometry).unwrap();
    r
}

#[test]
fn a_splat_behind_an_obstacle_is_hidden_and_one_in_front_is_drawn() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let behind = Splat::new(Vec3::new(-0.4, 0.0, -0.5), Vec3::Z, 0.2);
    let front = Splat::new(Vec3::new(0.4, 0.0, 0.5), Vec3::Z, 0.2);
    let wall = SceneGeometry {
        objects: vec![box_object(
            Vec3::new(-1.0, -0.5, -0.1),
            Vec3::new(1.0, 0.5, 0.1),
            Vec3::splat(0.6),
        )],
        ..Default::default()
    };
    let env = Environment::procedural();
    for (geometry, hidden) in [(SceneGeometry::default(), false), (wall, true)] {
        let mut r = renderer(ctx, &env, &geometry);
        r.upload(ctx, &[behind, front]).unwrap();
        r.render(ctx, &camera(), &Shading::default()).unwrap();
        let acc = r.read_accumulation(ctx).unwrap();
        let (bx, by) = pixel(behind.position);
        let (fx, fy) = pixel(front.position);
        assert!(acc.weight(fx, fy) > 0.9, "the front splat is drawn");
        if hidden {
            assert_eq!(acc.weight(bx, by), 0.0, "the splat behind the wall shows");
            // The depth there is the wall's front face, z = 0.1: a view
            // depth of 2.9.
            let depth = r.read_depth(ctx).unwrap()[(by * W + bx) as usize];
            let (near, far) = (camera().near, camera().far);
            let z = near * far / (far - depth * (far - near));
            assert!((z - 2.9).abs() < 1e-3, "view depth {z} at the wall");
        } else {
            assert!(acc.weight(bx, by) > 0.9, "without the wall both show");
        }
        // The debug views show the fluid alone, hidden by the geometry as
        // the shaded view is: black behind the wall, lit in front.
        for view in [View::Normals, View::Weights, View::Depth] {
            let shading = Shading {
                view,
                ..Default::default()
            };
            r.render(ctx, &camera(), &shading).unwrap();
            let image = r.read_image(ctx).unwrap();
            let lit = |x, y| image.get_pixel(x, y).0[..3].iter().any(|&c| c > 20);
            assert!(lit(fx, fy), "{view:?}: the front splat");
            assert_eq!(lit(bx, by), !hidden, "{view:?}: the splat behind the wall");
        }
    }
}

#[test]
fn the_refraction_shows_the_geometry_behind_the_fluid() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let sheet = Splat::new(Vec3::new(0.0, 0.0, 0.5), Vec3::Z, 0.6);
    // Straight through: no offset, no reflection, all light passes.
    let shading = Shading {
        refraction: 0.0,
        reflectivity: 0.0,
        fluid_colour: Vec3::ONE,
        ..Default::default()
    };
    let env = grey_environment(128);
    let behind = |colour| SceneGeometry {
        objects: vec![box_object(
            Vec3::new(-0.3, -0.3, -0.6),
            Vec3::new(0.3, 0.3, -0.4),
            colour,
        )],
        ..Default::default()
    };
    let (x, y) = pixel(Vec3::ZERO);
    let mut seen = Vec::new();
    for colour in [Vec3::new(0.9, 0.1, 0.1), Vec3::new(0.1, 0.9, 0.1)] {
        let mut r = renderer(ctx, &env, &behind(colour));
        // The box alone, then behind the sheet.
        r.upload(ctx, &[]).unwrap();
        r.render(ctx, &camera(), &shading).unwrap();
        let bare = r.read_image(ctx).unwrap().get_pixel(x, y).0;
        r.upload(ctx, &[sheet]).unwrap();
        r.render(ctx, &camera(), &shading).unwrap();
        let acc = r.read_accumulation(ctx).unwrap();
        assert!(acc.weight(x, y) > 0.9, "the sheet covers the pixel");
        let through = r.read_image(ctx).unwrap().get_pixel(x, y).0;
        for c in 0..3 {
            assert!(
                bare[c].abs_diff(through[c]) <= 1,
                "through the fluid {through:?}, the box alone {bare:?}"
            );
        }
        seen.push(through);
    }
    let (red, green) = (seen[0], seen[1]);
    assert!(
        red[0] > 2 * red[1] && green[1] > 2 * green[0],
        "red box {red:?}, green box {green:?}"
    );
    // Not the grey (128) backdrop.
    assert!(
        red[1] < 64 && green[0] < 64,
        "red box {red:?}, green box {green:?}"
    );
}

/// Splats tiling the faces of the box (min, max), outward normals.
fn splat_box(min: Vec3, max: Vec3, spacing: f32) -> Vec<Splat> {
    let mut splats = Vec::new();
    let r = 0.8 * spacing;
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let steps = |k: usize| ((max[k] - min[k]) / spacing).round() as i32;
        for side in [min[axis], max[axis]] {
            let mut n = Vec3::ZERO;
            n[axis] = if side == max[axis] { 1.0 } else { -1.0 };
            for i in 0..=steps(u) {
                for j in 0..=steps(v) {
                    let mut p = Vec3::ZERO;
                    p[axis] = side;
                    p[u] = min[u] + i as f32 * spacing;
                    p[v] = min[v] + j as f32 * spacing;
                    splats.push(Splat::new(p, n, r));
                }
            }
        }
    }
    splats
}

#[test]
fn deep_fluid_is_more_saturated_than_a_thin_sheet_by_beer_lambert() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let shading = Shading {
        refraction: 0.0,
        reflectivity: 0.0,
        fluid_colour: Vec3::ONE,
        absorption: Vec3::new(4.0, 1.0, 0.25),
        depth_epsilon: 0.01,
        ..Default::default()
    };
    let level = 200u8;
    let env = grey_environment(level);
    let mut r = renderer(ctx, &env, &SceneGeometry::default());
    let (x, y) = pixel(Vec3::ZERO);
    let mut measured = Vec::new();
    for depth in [0.4f32, 0.02] {
        let half = Vec3::new(0.3, 0.3, 0.5 * depth);
        r.upload(ctx, &splat_box(-half, half, 0.02)).unwrap();
        r.render(ctx, &camera(), &shading).unwrap();
        let px = r.read_image(ctx).unwrap().get_pixel(x, y).0;
        let rgb = Vec3::new(px[0] as f32, px[1] as f32, px[2] as f32);
        let expected = level as f32 * transmittance(&shading, depth);
        println!("thickness {depth} m: pixel {rgb}, Beer–Lambert {expected}");
        assert!(
            (rgb - expected).abs().max_element() <= 2.0,
            "thickness {depth}: pixel {rgb}, expected {expected}"
        );
        // Saturation (max − min) / max.
        measured.push((rgb.max_element() - rgb.min_element()) / rgb.max_element());
    }
    let (deep, thin) = (measured[0], measured[1]);
    println!("saturation: deep {deep:.3}, thin sheet {thin:.3}");
    assert!(deep > 0.7 && thin < 0.08, "deep {deep}, thin {thin}");

    // Without absorption the thickness pass does not run and both are grey.
    let plain = Shading {
        absorption: Vec3::ZERO,
        ..shading
    };
    r.upload(ctx, &splat_box(Vec3::splat(-0.2), Vec3::splat(0.2), 0.02))
        .unwrap();
    r.render(ctx, &camera(), &plain).unwrap();
    let px = r.read_image(ctx).unwrap().get_pixel(x, y).0;
    assert!(px[..3].iter().all(|&c| c.abs_diff(level) <= 1), "{px:?}");
}

#[test]
fn the_environment_backdrop_and_bad_geometry() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let env = Environment::procedural();
    let sky = SceneGeometry {
        backdrop: Backdrop::Environment,
        ..Default::default()
    };
    let mut r = renderer(ctx, &env, &sky);
    r.upload(ctx, &[]).unwrap();
    // Looking up from below the horizon: the top of the image is sky blue,
    // the bottom the environment's floor.
    let cam = Camera::looking_at(Vec3::ZERO, Vec3::new(0.0, 0.05, -1.0));
    r.render(ctx, &cam, &Shading::default()).unwrap();
    let image = r.read_image(ctx).unwrap();
    let top = image.get_pixel(W / 2, 2).0;
    let bottom = image.get_pixel(W / 2, H - 2).0;
    assert!(top[2] > top[0] + 30, "sky {top:?}");
    assert!(bottom[0] >= bottom[2], "floor {bottom:?}");

    let bad = SceneGeometry {
        objects: vec![Object {
            mesh: Mesh::cuboid(Vec3::ZERO, Vec3::ONE).unwrap(),
            material: Material::plain(Vec3::new(f32::NAN, 0.0, 0.0)),
        }],
        ..Default::default()
    };
    let err = r.set_geometry(ctx, &bad).unwrap_err().to_string();
    assert!(err.contains("colour"), "{err}");
}
