//! The splat renderer against a reference: a CPU ray caster of the same
//! particles' iso-surface c(x) = 0.5 (`surfel_extract::raycast`) seen by the same
//! camera and shaded by the same equations (`splat_render::shading::shade_pixel`).
//! Checks each case's silhouette IoU, median normal error and FLIP mean
//! against the ray caster's image at its measured value plus a margin
//! (`Case`), and compares each splat image with a stored golden image
//! (`tests/golden/*.png`) by FLIP, within 0.002 (measured at most 0.0002).
//! The goldens guard what the ray caster cannot see (a shading change made
//! in both the shader and `shade_pixel`); the ray caster guards the goldens,
//! which the test writes itself.
//!
//! Regenerate the golden images with `SPH_UPDATE_GOLDEN=1 cargo test --release
//! --test reference_render`. Every run also leaves `{case}-splats.png`,
//! `{case}-raycast.png` and `{case}-silhouettes.png` (red: splats only, blue:
//! iso-surface only) in `target/tmp/`. GPU tests skip without an adapter unless
//! `SPH_REQUIRE_GPU=1`.

use std::path::PathBuf;

use glam::{Vec2, Vec3};
use image::RgbaImage;
use rayon::prelude::*;
use sph_core::Scene;
use splat_render::shading::shade_pixel;
use splat_render::{Camera, Environment, GpuContext, Shading, Splat, SplatPath, SplatRenderer};
use surfel_extract::raycast::Raycaster;
use surfel_extract::samples::jittered_lattice;
use surfel_extract::{ColourField, ExtractParams, Surface, extract_field};

const W: u32 = 512;
const H_PX: u32 = 384;
const SPACING: f32 = 0.01;
const H: f32 = 2.0 * SPACING;

/// The tests' jittered lattice of `SPACING` cut by `keep`.
fn lattice(n: i32, keep: impl Fn(Vec3) -> bool) -> Vec<Vec3> {
    jittered_lattice(n, SPACING, 0.3, 5, keep)
}

/// A scene of particles, its camera, and what the splats must reach
/// against the ray caster: each bound is the value measured on lavapipe
/// (2026-11-26, in the comment beside it) plus a margin: 0.004 in IoU
/// (rounded down to three places), about 0.3° in the median normal error
/// and about a quarter in the FLIP mean.
struct Case {
    name: &'static str,
    field: ColourField,
    camera: Camera,
    /// Silhouette IoU the splats must reach.
    min_iou: f64,
    /// The largest median angle (degrees) between the splats' normals and
    /// the iso-surface's.
    max_normal_error: f32,
    /// The largest FLIP mean between the splat image and the ray-cast one.
    max_flip: f32,
}

fn cases() -> Vec<Case> {
    let sphere = lattice(9, |x| x.length() <= 8.5 * SPACING);
    let block = lattice(7, |x| {
        x.x < 5.5 * SPACING && x.z > -4.5 * SPACING && x.y < 6.0 * SPACING
    });
    let mut world = Scene::dam_break(0.2, 0.06, 0.02)
        .build_world()
        .expect("built-in scene");
    world.advance(0.4).expect("dam break runs");
    let anisotropic = |x: &[Vec3]| {
        let mut field = ColourField::new(Surface::anisotropic()).unwrap();
        field.refill_from_positions(x, H).unwrap();
        field
    };
    let pair = [
        Vec3::new(-0.5 * SPACING, 0.0, 0.0),
        Vec3::new(0.5 * SPACING, 0.0, 0.0),
    ];
    vec![
        Case {
            name: "sphere-anisotropic",
            field: anisotropic(&sphere),
            camera: Camera::looking_at(Vec3::new(0.12, 0.18, 0.3), Vec3::ZERO),
            // Measured: IoU 0.9970, 0.69°, FLIP 0.0150.
            min_iou: 0.993,
            max_normal_error: 1.0,
            max_flip: 0.019,
        },
        Case {
            name: "block-anisotropic",
            field: anisotropic(&block),
            camera: Camera::looking_at(Vec3::new(0.25, 0.2, 0.25), Vec3::new(0.0, -0.01, 0.0)),
            // Measured: IoU 0.9941, 0.64°, FLIP 0.0152.
            min_iou: 0.990,
            max_normal_error: 0.95,
            max_flip: 0.019,
        },
        // Droplets: one particle, and a pair a spacing apart, whose
        // anisotropic kernels are spheres of half h (too few neighbours
        // for a covariance).
        Case {
            name: "droplet",
            field: anisotropic(&[Vec3::ZERO]),
            camera: Camera::looking_at(Vec3::new(0.008, 0.012, 0.02), Vec3::ZERO),
            // Measured: IoU 0.9727, 3.19°, FLIP 0.0797.
            min_iou: 0.968,
            max_normal_error: 3.5,
            max_flip: 0.095,
        },
        Case {
            name: "pair",
            field: anisotropic(&pair),
            camera: Camera::looking_at(Vec3::new(0.012, 0.018, 0.03), Vec3::ZERO),
            // Measured: IoU 0.9837, 0.93°, FLIP 0.0186.
            min_iou: 0.979,
            max_normal_error: 1.25,
            max_flip: 0.023,
        },
        Case {
            name: "sphere",
            field: ColourField::from_positions(&sphere, H).unwrap(),
            camera: Camera::looking_at(Vec3::new(0.12, 0.18, 0.3), Vec3::ZERO),
            // Measured: IoU 0.9953, 0.85°, FLIP 0.0162.
            min_iou: 0.991,
            max_normal_error: 1.15,
            max_flip: 0.020,
        },
        Case {
            name: "block",
            field: ColourField::from_positions(&block, H).unwrap(),
            camera: Camera::looking_at(Vec3::new(0.25, 0.2, 0.25), Vec3::new(0.0, -0.01, 0.0)),
            // Measured: IoU 0.9947, 0.72°, FLIP 0.0145.
            min_iou: 0.990,
            max_normal_error: 1.0,
            max_flip: 0.018,
        },
        Case {
            name: "dam-break",
            field: ColourField::from_particles(&world.particles, world.params().h).unwrap(),
            camera: Camera::looking_at(Vec3::new(0.1, 0.2, 0.45), Vec3::new(0.1, 0.03, 0.0)),
            // A coarse (3 particles deep) slab with thin jets and a droplet: a
            // long silhouette, so the overhang of flat discs weighs most here.
            // Measured: IoU 0.9870, 0.89°, FLIP 0.0245 (with the scenes'
            // default clearance; 0.9887, 1.46° and 0.0297 without it).
            min_iou: 0.984,
            max_normal_error: 1.2,
            max_flip: 0.031,
        },
    ]
}

/// Ray-cast reference: per pixel the iso-surface normal where a ray hits.
fn reference_normals(field: &ColourField, camera: &Camera) -> Vec<Option<Vec3>> {
    let caster = Raycaster::new(field, 0.5, field.h() / 8.0).expect("the reference's settings");
    (0..W * H_PX)
        .into_par_iter()
        .map(|i| {
            let (o, d) = camera.pixel_ray(i % W, i / W, W, H_PX);
            caster.cast(o, d).map(|hit| hit.normal)
        })
        .collect()
}

fn shade_cpu(
    normals: &[Option<Vec3>],
    camera: &Camera,
    env: &Environment,
    shading: &Shading,
) -> RgbaImage {
    let view = camera.view();
    RgbaImage::from_fn(W, H_PX, |x, y| {
        let (_, d) = camera.pixel_ray(x, y, W, H_PX);
        let uv = Vec2::new((x as f32 + 0.5) / W as f32, (y as f32 + 0.5) / H_PX as f32);
        let c = shade_pixel(normals[(y * W + x) as usize], d, uv, &view, env, shading);
        let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
        image::Rgba([q(c.x), q(c.y), q(c.z), 255])
    })
}

/// FLIP error map and its mean (nv-flip: NVIDIA's perceptual image difference).
fn flip(reference: &RgbaImage, test: &RgbaImage) -> (f32, RgbaImage) {
    let rgb = |img: &RgbaImage| {
        let rgb = image::DynamicImage::ImageRgba8(img.clone()).into_rgb8();
        nv_flip::FlipImageRgb8::with_data(rgb.width(), rgb.height(), &rgb)
    };
    let error = nv_flip::flip(
        rgb(reference),
        rgb(test),
        nv_flip::DEFAULT_PIXELS_PER_DEGREE,
    );
    let mean = nv_flip::FlipPool::from_image(&error).mean();
    let vis = error.apply_color_lut(&nv_flip::magma_lut());
    let rgb = image::RgbImage::from_raw(vis.width(), vis.height(), vis.to_vec()).expect("size");
    (mean, image::DynamicImage::ImageRgb8(rgb).into_rgba8())
}

#[test]
fn splats_match_the_ray_cast_iso_surface() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let env = Environment::procedural();
    let shading = Shading {
        depth_epsilon: 0.5 * H,
        ..Default::default()
    };
    let mut renderer = SplatRenderer::new(ctx, W, H_PX, &env).unwrap();
    let golden_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden");
    let failures_dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("golden-failures");
    let update = std::env::var("SPH_UPDATE_GOLDEN").is_ok_and(|v| v == "1");
    let mut golden_failures = Vec::new();
    let mut measured = std::collections::HashMap::new();
    for case in cases() {
        // Three refinement iterations and initial discs of 0.2 h. A flat disc of
        // radius r tangent to a surface of curvature radius R overhangs its
        // silhouette by about r²/2R, so the disc size sets the silhouette error;
        // hole closing keeps the smaller discs gap-free. Measured on the
        // dam-break frame (IoU, holes, surfels): 0.4 h → 0.943, 0, 9,272;
        // 0.3 h → 0.969, 3 px, 9,868; 0.25 h → 0.978, 0, 11,052;
        // 0.2 h → 0.985, 0, 14,108. The frame is a splash, so its shape
        // follows the solver's rounding: since the density sums lane-wise
        // (`Neighbourhood::poly6_sums`) it is 0.25 h → 0.966, 33,843 surfels
        // and 0.2 h → 0.977, 55,816; with the 3×3 first split
        // (`Split::ThreeByThree`, the default since) 0.2 h → 0.978, 68,953;
        // since the forces sum lane-wise too (`Neighbourhood::force_sums`)
        // 0.2 h → 0.988, 69,269.
        let params = ExtractParams {
            iterations: 3,
            radius: 0.2,
            ..ExtractParams::new(case.field.h())
        };
        let surfels = extract_field(&case.field, &params).unwrap();
        let splats: Vec<Splat> = surfels
            .surfels
            .iter()
            .map(|s| Splat::new(s.position, s.normal, s.radius))
            .collect();
        renderer.upload(ctx, &splats).unwrap();
        renderer.render(ctx, &case.camera, &shading).unwrap();
        let acc = renderer.read_accumulation(ctx).unwrap();
        let image = renderer.read_image(ctx).unwrap();

        let reference = reference_normals(&case.field, &case.camera);
        let (mut both, mut either, mut angles, mut holes) = (0usize, 0usize, Vec::new(), 0usize);
        for y in 0..H_PX {
            for x in 0..W {
                let splat = acc.normalised(x, y);
                let cast = reference[(y * W + x) as usize];
                either += usize::from(splat.is_some() || cast.is_some());
                holes += usize::from(splat.is_none() && cast.is_some());
                if let (Some(a), Some(b)) = (splat, cast) {
                    both += 1;
                    angles.push(a.normalize().dot(b).clamp(-1.0, 1.0).acos().to_degrees());
                }
            }
        }
        let iou = both as f64 / either.max(1) as f64;
        angles.sort_by(f32::total_cmp);
        let median_angle = angles.get(angles.len() / 2).copied().unwrap_or(f32::NAN);
        let reference_image = shade_cpu(&reference, &case.camera, &env, &shading);
        let (flip_mean, _) = flip(&reference_image, &image);
        let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
        image
            .save(out.join(format!("{}-splats.png", case.name)))
            .unwrap();
        reference_image
            .save(out.join(format!("{}-raycast.png", case.name)))
            .unwrap();
        let mask = RgbaImage::from_fn(W, H_PX, |x, y| {
            let s = acc.normalised(x, y).is_some();
            let c = reference[(y * W + x) as usize].is_some();
            image::Rgba([
                if s && !c { 255 } else { 0 },
                if s && c { 160 } else { 0 },
                if c && !s { 255 } else { 0 },
                255,
            ])
        });
        mask.save(out.join(format!("{}-silhouettes.png", case.name)))
            .unwrap();
        println!(
            "{}: {} surfels, silhouette IoU {iou:.4} ({both} of {either} px), median normal error {median_angle:.2}°, {holes} px hole, FLIP mean vs ray-cast reference {flip_mean:.4}",
            case.name,
            splats.len()
        );
        assert!(
            both > 2_000,
            "{}: the surface fills only {both} pixels",
            case.name
        );
        assert!(
            iou >= case.min_iou,
            "{}: silhouette IoU {iou:.4} < {}",
            case.name,
            case.min_iou
        );
        assert_eq!(
            holes, 0,
            "{}: pixels where the iso-surface shows but no splat does",
            case.name
        );
        measured.insert(case.name, (iou, median_angle));
        assert!(
            median_angle <= case.max_normal_error,
            "{}: median normal error {median_angle:.2}° > {}°",
            case.name,
            case.max_normal_error
        );
        assert!(
            flip_mean <= case.max_flip,
            "{}: FLIP mean against the ray-cast reference {flip_mean:.4} > {}",
            case.name,
            case.max_flip
        );

        // The compute splat path draws the same picture.
        renderer.set_splat_path(ctx, SplatPath::Compute).unwrap();
        renderer.render(ctx, &case.camera, &shading).unwrap();
        let computed = renderer.read_image(ctx).unwrap();
        renderer.set_splat_path(ctx, SplatPath::Raster).unwrap();
        let (compute_mean, _) = flip(&image, &computed);
        println!(
            "{}: FLIP mean of the compute path vs raster {compute_mean:e}",
            case.name
        );
        if compute_mean > 0.01 {
            computed
                .save(out.join(format!("{}-compute.png", case.name)))
                .unwrap();
        }
        assert!(
            compute_mean <= 0.01,
            "{}: compute splatting differs from raster splatting by FLIP {compute_mean:.4}",
            case.name
        );

        let golden_path = golden_dir.join(format!("{}.png", case.name));
        if update {
            image.save(&golden_path).expect("write golden image");
            continue;
        }
        let golden = image::open(&golden_path)
            .unwrap_or_else(|e| {
                panic!(
                    "{}: {e}; run with SPH_UPDATE_GOLDEN=1",
                    golden_path.display()
                )
            })
            .into_rgba8();
        let (golden_mean, difference) = flip(&golden, &image);
        println!("{}: FLIP mean vs golden {golden_mean:.4}", case.name);
        if golden.dimensions() != image.dimensions() || golden_mean > 0.002 {
            std::fs::create_dir_all(&failures_dir).unwrap();
            image
                .save(failures_dir.join(format!("{}-actual.png", case.name)))
                .unwrap();
            difference
                .save(failures_dir.join(format!("{}-difference.png", case.name)))
                .unwrap();
            golden_failures.push(format!("{} (FLIP mean {golden_mean:.4})", case.name));
        }
    }
    // The anisotropic field against the thesis's on the same shapes: its
    // splats match its ray-cast surface at least as well (measured: sphere
    // IoU 0.9970 against 0.9953, 0.69° against 0.85°; block 0.9941 against
    // 0.9947, 0.64° against 0.72°), to 0.002 of IoU and 0.2° for the
    // rasteriser's rounding. (The dam-break frame on the anisotropic field
    // is not yet a case: IoU 0.9671 with 640 px of holes, issue 28.)
    for shape in ["sphere", "block"] {
        let (iou, angle) = measured[shape];
        let (a_iou, a_angle) = measured[format!("{shape}-anisotropic").as_str()];
        assert!(
            a_iou >= iou - 0.002,
            "{shape}: anisotropic IoU {a_iou}, isotropic {iou}"
        );
        assert!(
            a_angle <= angle + 0.2,
            "{shape}: anisotropic {a_angle}°, isotropic {angle}°"
        );
    }
    assert!(
        golden_failures.is_empty(),
        "differ from tests/golden: {golden_failures:?}; actual and difference images in {}",
        failures_dir.display()
    );
}

/// Holes in the GPU path's surface: surfels extracted on the GPU as the demo
/// extracts them (the anisotropic field, hole closing, two iterations, discs
/// of h/2; first splits 2×2) rendered against the ray-cast iso-surface of the
/// same field, beside the GPU without hole closing (anisotropic and the
/// thesis's isotropic field, the demo's GPU surface before) and the CPU with
/// the same parameters. A hole is a pixel where the iso-surface shows and no
/// splat does. Asserted: on the sphere and on the splashing dam-break frame,
/// fewer than 0.1 % of the surface's pixels through either path with hole
/// closing (measured: none on the sphere; 0.016 % on the GPU and 0.024 % on
/// the CPU on the dam-break frame, where 1.3 % and 1.5 % were left while
/// hole closing took discs a quarter of h thick).
#[test]
fn gpu_splats_close_the_anisotropic_surface() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let env = Environment::procedural();
    let shading = Shading {
        depth_epsilon: 0.5 * H,
        ..Default::default()
    };
    let mut renderer = SplatRenderer::new(ctx, W, H_PX, &env).unwrap();
    let sphere = lattice(9, |x| x.length() <= 8.5 * SPACING);
    let mut world = Scene::dam_break(0.2, 0.06, 0.02)
        .build_world()
        .expect("built-in scene");
    world.advance(0.4).expect("dam break runs");
    let dam_camera = Camera::looking_at(Vec3::new(0.1, 0.2, 0.45), Vec3::new(0.1, 0.03, 0.0));
    let sphere_camera = Camera::looking_at(Vec3::new(0.12, 0.18, 0.3), Vec3::ZERO);
    let dam = world.particles.positions().to_vec();
    for (name, x, h, camera) in [
        ("sphere", &sphere[..], H, &sphere_camera),
        ("dam-break", &dam[..], world.params().h, &dam_camera),
    ] {
        let mut fractions = Vec::new();
        let covered = ExtractParams {
            first_split: surfel_extract::Split::TwoByTwo,
            ..ExtractParams::new(h)
        };
        let thesis = covered.thesis();
        for (path, surface, mode) in [
            (
                "GPU, anisotropic, hole closing",
                Surface::anisotropic(),
                &covered,
            ),
            (
                "GPU, anisotropic, thesis mode",
                Surface::anisotropic(),
                &thesis,
            ),
            ("GPU, isotropic, thesis mode", Surface::Isotropic, &thesis),
            (
                "CPU, anisotropic, hole closing",
                Surface::anisotropic(),
                &covered,
            ),
        ] {
            let mut field = ColourField::new(surface).unwrap();
            field.refill_from_positions(x, h).unwrap();
            let params = ExtractParams { surface, ..*mode };
            let surfels = if path.starts_with("CPU") {
                extract_field(&field, &params).unwrap().surfels
            } else {
                let mut gpu =
                    sph_gpu::GpuExtractor::new(&ctx.device, x.len(), 1 << 21, &params).unwrap();
                gpu.upload_field(&ctx.queue, &field).unwrap();
                let mut encoder = ctx.device.create_command_encoder(&Default::default());
                gpu.encode(&mut encoder);
                ctx.queue.submit([encoder.finish()]);
                gpu.read_surfels(&ctx.device, &ctx.queue).unwrap().0
            };
            let splats: Vec<Splat> = (surfels.iter())
                .map(|s| Splat::new(s.position, s.normal, s.radius))
                .collect();
            renderer.upload(ctx, &splats).unwrap();
            renderer.render(ctx, camera, &shading).unwrap();
            let acc = renderer.read_accumulation(ctx).unwrap();
            let reference = reference_normals(&field, camera);
            let (mut surface_px, mut holes) = (0usize, 0usize);
            for y in 0..H_PX {
                for x in 0..W {
                    if reference[(y * W + x) as usize].is_some() {
                        surface_px += 1;
                        holes += usize::from(acc.normalised(x, y).is_none());
                    }
                }
            }
            let fraction = holes as f64 / surface_px.max(1) as f64;
            println!(
                "{name} ({path}): {} surfels, {holes} of {surface_px} surface pixels uncovered ({:.3} %)",
                surfels.len(),
                100.0 * fraction
            );
            assert!(surface_px > 2_000, "{name}: {surface_px} px");
            fractions.push(fraction);
        }
        let [gpu, _, _, cpu] = fractions[..] else {
            unreachable!("four paths")
        };
        assert!(
            gpu < 0.001 && cpu < 0.001,
            "{name}: {:.3} % holes on the GPU, {:.3} % on the CPU",
            100.0 * gpu,
            100.0 * cpu
        );
    }
}

/// The settled pool (issue 41's, 0.6 × 0.2 × 0.6 m at 2 cm, 2 s of DFSPH)
/// through both paths with the demo's extraction parameters (anisotropic
/// field, hole closing, 3×3 first splits): the GPU's surfels within 10 % of
/// the CPU's in number and its frame within a FLIP mean of 0.05 (issue 44).
#[test]
fn settled_pool_renders_alike_from_the_gpu_and_the_cpu_extraction() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let mut scene = Scene::dam_break(0.15, 0.6, 0.02).with_solver(sph_core::SolverKind::Dfsph);
    scene.domain.min = [0.0; 3];
    scene.domain.max = [0.6, 0.4, 0.6];
    scene.blocks[0].min = [0.0; 3];
    scene.blocks[0].max = [0.6, 0.2, 0.6];
    let mut world = scene.build_world().unwrap();
    for _ in 0..120 {
        world.advance(1.0 / 60.0).unwrap();
    }
    let p = &world.particles;
    let h = scene.fluid.h;
    let params = ExtractParams::new(h).anisotropic();
    let mut field = ColourField::new(params.surface).unwrap();
    field.refill_from_particles(p, h).unwrap();
    let cpu = extract_field(&field, &params).unwrap().surfels;
    let mut gpu = sph_gpu::GpuExtractor::new(&ctx.device, p.len(), 1 << 21, &params).unwrap();
    gpu.upload(&ctx.queue, p.positions(), field.volumes())
        .unwrap();
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    gpu.encode(&mut encoder);
    ctx.queue.submit([encoder.finish()]);
    let (surfels, stats) = gpu.read_surfels(&ctx.device, &ctx.queue).unwrap();
    assert_eq!(stats.dropped, 0);
    let env = Environment::procedural();
    let shading = Shading {
        depth_epsilon: 0.5 * h,
        ..Default::default()
    };
    let camera = Camera::looking_at(Vec3::new(0.9, 0.6, 1.1), Vec3::new(0.3, 0.1, 0.3));
    let mut renderer = SplatRenderer::new(ctx, W, H_PX, &env).unwrap();
    let mut image = |surfels: &[surfel_extract::Surfel]| {
        let splats: Vec<Splat> = (surfels.iter())
            .map(|s| Splat::new(s.position, s.normal, s.radius))
            .collect();
        renderer.upload(ctx, &splats).unwrap();
        renderer.render(ctx, &camera, &shading).unwrap();
        renderer.read_image(ctx).unwrap()
    };
    let (from_cpu, from_gpu) = (image(&cpu), image(&surfels));
    let (mean, _) = flip(&from_cpu, &from_gpu);
    println!(
        "settled pool: GPU {} surfels, CPU {}; FLIP {mean:.4}",
        surfels.len(),
        cpu.len()
    );
    let diff = (surfels.len() as f64 - cpu.len() as f64).abs();
    assert!(diff <= 0.1 * cpu.len() as f64, "surfel counts");
    assert!(mean <= 0.05, "FLIP {mean}");
}
