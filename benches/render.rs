//! `cargo bench --bench render`: one whole splat frame — upload, scene pass,
//! visibility pass, attribute pass, normalise-and-shade compute pass, waiting
//! for the GPU to finish (no readback) — for 20k, 100k and 1M surfels at
//! 1280×720 and 1920×1080. Throughput is in surfels. The surfels tile a unit
//! sphere (Fibonacci lattice, radii overlapping their neighbours) that fills
//! about half the frame. On a machine without a GPU this runs on lavapipe:
//! CPU-rasteriser figures.
//!
//! Each size runs twice: `WxH` through the raster splat passes,
//! `compute-WxH` through the compute ones (`SplatPath::Compute`).
//!
//! The group `drawn` times the 1920×1080 frames of both paths without the
//! upload, as the GPU path draws its surfels (they never leave the GPU): at
//! 1M surfels the upload is most of a `render` row's time on a datacenter
//! GPU.
//!
//! The group `scenery` times the same frame at 1920×1080, on the adapter's
//! splat path (`SplatPath::for_device`), without scene geometry (`bare`),
//! with the demo's kind (`geometry`: an open tank around the sphere, a
//! sphere obstacle, the ground and the environment's sky), and with that
//! plus Beer–Lambert absorption (`geometry+absorption`, which adds the back
//! surface pass).

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use splat_render::{
    Backdrop, Camera, Environment, GpuContext, Material, Mesh, Object, SceneGeometry, Shading,
    Splat, SplatPath, SplatRenderer, wgpu,
};

/// `n` surfels on the unit sphere, each with radius 1.5 × the mean spacing.
fn sphere(n: usize) -> Vec<Splat> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let spacing = (4.0 * std::f32::consts::PI / n as f32).sqrt();
    (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).sqrt();
            let a = golden * i as f32;
            let p = Vec3::new(r * a.cos(), y, r * a.sin());
            Splat::new(p, p, 1.5 * spacing)
        })
        .collect()
}

fn render(c: &mut Criterion) {
    let ctx = match GpuContext::headless() {
        Ok(ctx) => ctx,
        Err(err) => {
            println!("skipped: {err}");
            return;
        }
    };
    println!("adapter: {}", ctx.adapter_summary());
    let env = Environment::procedural();
    let camera = Camera::looking_at(Vec3::new(0.0, 0.8, 3.2), Vec3::ZERO);
    let shading = Shading {
        depth_epsilon: 0.02,
        ..Default::default()
    };
    let sizes = [(1280, 720), (1920, 1080)];
    for (group_name, upload) in [("render", true), ("drawn", false)] {
        let mut group = c.benchmark_group(group_name);
        group.sample_size(10);
        for (w, h) in sizes.into_iter().filter(|&(w, _)| upload || w == 1920) {
            for path in [SplatPath::Raster, SplatPath::Compute] {
                let mut renderer = SplatRenderer::new(&ctx, w, h, &env).expect("renderer");
                renderer.set_splat_path(&ctx, path).expect("splat path");
                let name = match path {
                    SplatPath::Raster => format!("{w}x{h}"),
                    SplatPath::Compute => format!("compute-{w}x{h}"),
                };
                for n in [20_000, 100_000, 1_000_000] {
                    let splats = sphere(n);
                    renderer.upload(&ctx, &splats).expect("upload");
                    group.throughput(Throughput::Elements(n as u64));
                    group.bench_function(BenchmarkId::new(&name, n), |b| {
                        b.iter(|| {
                            if upload {
                                renderer.upload(&ctx, black_box(&splats)).expect("upload");
                            }
                            renderer.render(&ctx, &camera, &shading).expect("render");
                            ctx.device
                                .poll(wgpu::PollType::wait_indefinitely())
                                .expect("GPU finished");
                        })
                    });
                }
            }
        }
        group.finish();
    }
}

/// The demo's kind of scenery around the unit sphere of surfels.
fn scenery() -> SceneGeometry {
    let stone = Material::tiled(Vec3::new(0.8, 0.78, 0.74), 0.2);
    SceneGeometry {
        objects: vec![
            Object {
                mesh: Mesh::container(Vec3::new(-1.6, -1.1, -1.6), Vec3::new(1.6, 1.4, 1.6))
                    .expect("tank"),
                material: stone,
            },
            Object {
                mesh: Mesh::ground(Vec3::ZERO, -1.11, 20.0).expect("ground"),
                material: Material::tiled(Vec3::new(0.62, 0.6, 0.55), 1.0),
            },
            Object {
                mesh: Mesh::sphere(Vec3::new(0.9, -0.7, 0.6), 0.4, 48).expect("obstacle"),
                material: Material::plain(Vec3::new(0.85, 0.42, 0.22)),
            },
        ],
        backdrop: Backdrop::Environment,
        ..Default::default()
    }
}

fn render_scenery(c: &mut Criterion) {
    let Ok(ctx) = GpuContext::headless() else {
        return;
    };
    let env = Environment::procedural();
    let camera = Camera::looking_at(Vec3::new(0.0, 1.4, 4.2), Vec3::new(0.0, -0.2, 0.0));
    let plain = Shading {
        depth_epsilon: 0.02,
        ..Default::default()
    };
    let absorbing = Shading {
        absorption: Vec3::new(6.0, 1.8, 0.7),
        ..plain
    };
    let mut group = c.benchmark_group("scenery");
    group.sample_size(10);
    let (w, h) = (1920, 1080);
    let mut renderer = SplatRenderer::new(&ctx, w, h, &env).expect("renderer");
    for n in [100_000, 1_000_000] {
        let splats = sphere(n);
        group.throughput(Throughput::Elements(n as u64));
        for (name, geometry, shading) in [
            ("bare", SceneGeometry::default(), plain),
            ("geometry", scenery(), plain),
            ("geometry+absorption", scenery(), absorbing),
        ] {
            renderer.set_geometry(&ctx, &geometry).expect("geometry");
            group.bench_function(BenchmarkId::new(name, n), |b| {
                b.iter(|| {
                    renderer.upload(&ctx, black_box(&splats)).expect("upload");
                    renderer.render(&ctx, &camera, &shading).expect("render");
                    ctx.device
                        .poll(wgpu::PollType::wait_indefinitely())
                        .expect("GPU finished");
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, render, render_scenery);
criterion_main!(benches);
