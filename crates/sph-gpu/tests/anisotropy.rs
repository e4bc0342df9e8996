//! The GPU's anisotropic kernels against surfel-extract's on the CPU: the
//! same neighbourhoods, clamps and centres, the eigen-decomposition in f32
//! there and f64 here.

use sph_core::glam::Vec3;
use sph_core::{NeighbourGrid, Scene, SolverKind};
use sph_gpu::GpuAnisotropy;
use splat_render::GpuContext;
use surfel_extract::Anisotropy;
use surfel_extract::anisotropy::{Centres, Ellipsoid, kernels};

/// The largest differences between the GPU's kernels and the CPU's, in
/// units of h for the centres (largest, 99th percentile) and of G²'s
/// largest entry for the kernels, how many isolated flags differ, and how
/// many kernels are isolated spheres and how many flattened (det G > 1.1);
/// printed for `label`.
fn compare(ctx: &GpuContext, label: &str, x: &[Vec3], h: f32, params: &Anisotropy) -> [f32; 6] {
    let grid = NeighbourGrid::build(x, params.radius * h).unwrap();
    let mut cpu = Vec::new();
    kernels(&grid, x, params, &mut cpu);
    let mut gpu = GpuAnisotropy::new(&ctx.device, x.len(), h, params).unwrap();
    let got = gpu.kernels_of(&ctx.device, &ctx.queue, x).unwrap();
    assert_eq!(got.len(), cpu.len());
    let (mut centre, mut shape, mut det, mut flags) = (0f32, 0f32, 0f32, 0);
    let mut centres = Vec::new();
    for ((gc, ge), (cc, ce)) in got.iter().zip(&cpu) {
        let e: &Ellipsoid = ce;
        let d = gc.distance(*cc) / h;
        centre = centre.max(d);
        centres.push(d);
        let scale = e.m.iter().fold(1f32, |m, v| m.max(v.abs()));
        for (a, b) in ge.m.iter().zip(e.m) {
            shape = shape.max((a - b).abs() / scale);
        }
        det = det.max((ge.det - e.det).abs() / e.det);
        flags += usize::from(ge.isolated != e.isolated);
    }
    let isolated = cpu.iter().filter(|(_, e)| e.isolated).count();
    let flat = cpu
        .iter()
        .filter(|(_, e)| !e.isolated && e.det > 1.1)
        .count();
    centres.sort_by(f32::total_cmp);
    let p99 = centres[centres.len() * 99 / 100];
    println!(
        "{label}: {} particles; centres differ by {centre:.2e} h at most ({p99:.2e} h at p99), \
         G² by {shape:.2e}, det G by {det:.2e} (relative), isolated flags {flags}; {isolated} isolated, {flat} flattened",
        x.len()
    );
    [
        centre,
        p99,
        shape.max(det),
        flags as f32,
        isolated as f32,
        flat as f32,
    ]
}

fn lattice(n: i32, s: f32) -> Vec<Vec3> {
    let mut x = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                x.push(Vec3::new(i as f32, j as f32, k as f32) * s);
            }
        }
    }
    x
}

/// A positions buffer that is too short or cannot be copied from is an
/// error naming it (a short one left stale positions in the grid; one
/// without `COPY_SRC` was a validation error, a panic under wgpu's default
/// handler); an h whose kernel coefficients overflow f32 is refused.
#[test]
fn bad_position_buffers_are_errors() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let params = Anisotropy::default();
    let e = GpuAnisotropy::new(&ctx.device, 10, 5e-5, &params)
        .err()
        .unwrap();
    assert!(e.to_string().contains("[1e-4, 1e3]"), "{e}");
    let mut gpu = GpuAnisotropy::new(&ctx.device, 10, 0.02, &params).unwrap();
    let buffer = |size, usage| {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size,
            usage,
            mapped_at_creation: false,
        })
    };
    use wgpu::BufferUsages as U;
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    let short = buffer(16 * 4, U::STORAGE | U::COPY_SRC);
    let e = gpu.encode(&ctx.queue, &mut encoder, &short, 5).unwrap_err();
    assert!(e.to_string().contains("fewer than n"), "{e}");
    let sealed = buffer(16 * 10, U::STORAGE);
    let e = gpu
        .encode(&ctx.queue, &mut encoder, &sealed, 5)
        .unwrap_err();
    assert!(e.to_string().contains("COPY_SRC"), "{e}");
    let good = buffer(16 * 10, U::STORAGE | U::COPY_SRC);
    gpu.encode(&ctx.queue, &mut encoder, &good, 10).unwrap();
    ctx.queue.submit([encoder.finish()]);
    ctx.check().unwrap();
}

/// A lattice block (faces, edges, corners, a jittered top) and scattered
/// particles around it (isolated spheres, pairs), with both kinds of
/// centres.
#[test]
fn gpu_kernels_match_the_cpu_on_a_block() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let s = 0.02;
    let mut x = lattice(10, s);
    let mut k = 1u32;
    let mut noise = move || {
        k = k.wrapping_mul(1_103_515_245).wrapping_add(12_345);
        (k >> 8) as f32 / (1u32 << 24) as f32 - 0.5
    };
    for p in x.iter_mut().filter(|p| p.y > 8.5 * s) {
        p.y += 0.4 * s * noise();
    }
    for i in 0..40 {
        let far = Vec3::new(
            0.4 + 0.1 * (i % 7) as f32,
            0.05 * (i / 7) as f32,
            0.3 * noise(),
        );
        x.push(far);
        if i % 3 == 0 {
            x.push(far + Vec3::splat(0.01));
        }
    }
    for params in [
        Anisotropy::default(),
        Anisotropy {
            centres: Centres::Mean,
            ..Anisotropy::default()
        },
    ] {
        let [centre, _, shape, flags, isolated, flat] = compare(ctx, "block", &x, 2.0 * s, &params);
        assert!(centre < 1e-4, "{centre}");
        assert!(shape < 1e-3, "{shape}");
        assert_eq!(flags, 0.0);
        assert!(isolated >= 40.0 && flat > 300.0, "{isolated} {flat}");
    }
}

/// A dam break half a second after release: splashing, thin sheets,
/// stray droplets.
#[test]
fn gpu_kernels_match_the_cpu_on_a_flow() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let scene = Scene::dam_break(0.2, 0.08, 0.02).with_solver(SolverKind::Pbf);
    let mut world = scene.build_world().unwrap();
    for _ in 0..30 {
        world.advance(1.0 / 60.0).unwrap();
    }
    let x = world.particles.positions().to_vec();
    let h = world.params().h;
    let [centre, p99, shape, flags, _, flat] =
        compare(ctx, "dam break", &x, h, &Anisotropy::default());
    assert!(p99 < 1e-4, "{p99}");
    assert!(centre < 1e-3, "{centre}");
    assert!(shape < 1e-3, "{shape}");
    assert_eq!(flags, 0.0);
    assert!(flat > 100.0, "{flat}");
}
