//! The GPU path against the CPU reference of sph-core: the grid gives the same
//! neighbour set for every particle, in a deterministic order; the density pass
//! the same densities and pressures. On lavapipe in CI; skipped
//! without an adapter unless `SPH_REQUIRE_GPU=1`.

use glam::Vec3;
use sph_core::NeighbourGrid;
use sph_gpu::GpuGrid;
use splat_render::GpuContext;

/// A jittered lattice with a far-away straggler and negative coordinates.
fn particles() -> Vec<Vec3> {
    let mut seed = 3u64;
    let mut noise = || {
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((seed >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    };
    let mut out = Vec::new();
    for k in -6..6 {
        for j in -4..10 {
            for i in -8..12 {
                let x = Vec3::new(i as f32, j as f32, k as f32) * 0.01;
                out.push(x + 0.004 * Vec3::new(noise(), noise(), noise()));
            }
        }
    }
    out.push(Vec3::new(1e4, -3e3, 42.0));
    out
}

/// Also with room for 40 times the particles: a hash table of 2,048 blocks
/// of 256 buckets, whose block totals the scan sums 8 to a thread.
#[test]
fn gpu_grid_finds_the_cpu_grids_neighbour_sets() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let x = particles();
    let h = 0.02;
    for capacity in [x.len(), 40 * x.len()] {
        let grid = GpuGrid::new(&ctx.device, capacity, h, 96).unwrap();
        neighbour_sets_match(ctx, &x, grid);
    }
}

/// A grid over a box has one bucket per cell, in x-fastest order; the
/// particles outside the box (half the lattice in one of the two boxes, and
/// the one far away in both) wrap onto cells inside and are found all the
/// same.
#[test]
fn gpu_grid_in_a_box_finds_the_cpu_grids_neighbour_sets() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let x = particles();
    let h = 0.02;
    for (min, max) in [
        (Vec3::new(-0.09, -0.05, -0.07), Vec3::new(0.13, 0.11, 0.07)),
        (Vec3::new(-0.03, 0.0, -0.02), Vec3::new(0.05, 0.04, 0.03)),
    ] {
        let grid = GpuGrid::in_box(&ctx.device, x.len(), h, 96, min, max).unwrap();
        assert!(grid.is_box());
        let cells = ((max - min) / h).floor() + 1.0;
        assert!(grid.table_size() as f32 >= cells.x * cells.y * cells.z);
        assert!((grid.table_size() as f32) < cells.x * cells.y * cells.z + 256.0);
        neighbour_sets_match(ctx, &x, grid);
    }
    // A box of more than 8 cells per particle is hashed instead.
    let big = GpuGrid::in_box(&ctx.device, 10, h, 8, Vec3::ZERO, Vec3::splat(1.0)).unwrap();
    assert!(!big.is_box());
}

fn neighbour_sets_match(ctx: &GpuContext, x: &[Vec3], mut grid: GpuGrid) {
    let h = grid.h();
    let cpu = NeighbourGrid::build(x, h).unwrap();
    println!("{} buckets", grid.table_size());
    grid.upload(&ctx.queue, x).unwrap();
    let lists = grid.neighbour_lists(&ctx.device, &ctx.queue).unwrap();
    let (mut pairs, mut ambiguous) = (0usize, 0usize);
    for (i, (len, gpu_list)) in lists.iter().enumerate() {
        assert_eq!(
            *len as usize,
            gpu_list.len(),
            "particle {i}: list cut at 96"
        );
        let mut expected = Vec::new();
        cpu.for_each_neighbour(i, |j, _, _| expected.push(j as u32));
        let (mut a, mut b) = (expected.clone(), gpu_list.clone());
        a.sort_unstable();
        b.sort_unstable();
        if a != b {
            // Only pairs at |r² − h²| within rounding may differ (FMA vs separate ops).
            let differing: Vec<u32> = a
                .iter()
                .filter(|j| !b.contains(j))
                .chain(b.iter().filter(|j| !a.contains(j)))
                .copied()
                .collect();
            for j in differing {
                let r2 = (x[i] - x[j as usize]).length_squared();
                assert!(
                    (r2 - h * h).abs() < 1e-6 * h * h,
                    "particle {i}: neighbour {j} at r² = {r2} differs"
                );
                ambiguous += 1;
            }
        }
        pairs += a.len();
    }
    println!(
        "{} particles, {pairs} neighbour pairs, {ambiguous} within rounding of h",
        x.len()
    );
    assert!(pairs > 20 * x.len(), "too few pairs: {pairs}");
    // Deterministic: a second build gives the same lists in the same order.
    let again = grid.neighbour_lists(&ctx.device, &ctx.queue).unwrap();
    assert_eq!(again, lists);
}

#[test]
fn bad_input_is_an_error() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    assert!(GpuGrid::new(&ctx.device, 10, 0.0, 8).is_err());
    // More particles than one dispatch of this device covers: an error that
    // names the limit, before anything is allocated.
    let groups = ctx.device.limits().max_compute_workgroups_per_dimension as usize;
    for capacity in [64 * groups + 1, 1 << 40] {
        match GpuGrid::new(&ctx.device, capacity, 0.1, 1) {
            Err(sph_gpu::GpuError::DeviceLimit(msg)) => {
                assert!(msg.contains(&capacity.to_string()), "{msg}")
            }
            Err(e) => panic!("{capacity}: wrong error {e}"),
            Ok(_) => panic!("{capacity} particles accepted"),
        }
    }
    let mut grid = GpuGrid::new(&ctx.device, 2, 0.1, 8).unwrap();
    assert!(grid.upload(&ctx.queue, &[Vec3::ZERO; 3]).is_err());
    assert!(grid.upload(&ctx.queue, &[Vec3::NAN]).is_err());
    grid.upload(&ctx.queue, &[]).unwrap();
    assert!(
        grid.neighbour_lists(&ctx.device, &ctx.queue)
            .unwrap()
            .is_empty()
    );
    // A density pass smaller than its grid would write past its buffers.
    let params = sph_core::FluidParams::water(0.1);
    let boundary = sph_core::Boundary::new(sph_core::Aabb::new(Vec3::splat(-1.0), Vec3::ONE));
    match sph_gpu::GpuDensity::new(&ctx.device, &grid, 1, &params, &boundary, &[]) {
        Err(e) => assert!(e.to_string().contains("capacity"), "{e}"),
        Ok(_) => panic!("a density pass for 1 particle on a grid of 2"),
    }
    sph_gpu::GpuDensity::new(&ctx.device, &grid, 2, &params, &boundary, &[]).unwrap();
    // sph-core's own checks, their reasons passed on.
    let bad_boundary = sph_core::Boundary {
        restitution: 2.0,
        ..boundary.clone()
    };
    let err = sph_gpu::GpuDensity::new(&ctx.device, &grid, 2, &params, &bad_boundary, &[])
        .err()
        .expect("a restitution of 2");
    assert!(err.to_string().contains("restitution"), "{err}");
    let mut particles = sph_core::Particles::new();
    particles.push(Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 0.0), 1.0);
    let err = sph_gpu::GpuSolver::new(&ctx.device, &ctx.queue, &particles, &params, &boundary)
        .err()
        .expect("a NaN velocity");
    assert!(err.to_string().contains("velocity"), "{err}");
    // Akinci et al.'s surface tension runs on the CPU only: refused, not
    // replaced by the colour field.
    let mut one = sph_core::Particles::new();
    one.push(Vec3::ZERO, Vec3::ZERO, 1.0);
    let akinci = sph_core::FluidParams {
        surface_tension_model: Some(sph_core::SurfaceTensionModel::Akinci),
        ..params
    };
    let err = sph_gpu::GpuSolver::new(&ctx.device, &ctx.queue, &one, &akinci, &boundary)
        .err()
        .expect("Akinci's surface tension");
    assert!(err.to_string().contains("surface_tension_model"), "{err}");

    // What `World::with_solver` refuses, the GPU solver refuses too: a
    // particle outside the domain (its first step moved it onto the wall),
    // a mass far too light for h, and an h whose kernel coefficients
    // overflow (5e-5 m: densities inf).
    let refuses = |particles: &sph_core::Particles, params: &sph_core::FluidParams, why: &str| {
        let err = sph_gpu::GpuSolver::new(&ctx.device, &ctx.queue, particles, params, &boundary)
            .err()
            .unwrap_or_else(|| panic!("accepted: {why}"));
        assert!(err.to_string().contains(why), "{err}");
    };
    let mut outside = sph_core::Particles::new();
    outside.push(Vec3::splat(2.0), Vec3::ZERO, 1.0);
    refuses(&outside, &params, "outside the domain");
    let mut light = sph_core::Particles::new();
    light.push(Vec3::ZERO, Vec3::ZERO, 1e-20);
    refuses(&light, &params, "too light for h");
    let tiny_h = sph_core::FluidParams::water(5e-5);
    let mut tiny = sph_core::Particles::new();
    tiny.push(Vec3::ZERO, Vec3::ZERO, 1e-9);
    refuses(&tiny, &tiny_h, "[1e-4, 1e3]");
    // A step below min_dt and a batch beyond MAX_BATCH.
    let mut solver =
        sph_gpu::GpuSolver::new(&ctx.device, &ctx.queue, &one, &params, &boundary).unwrap();
    assert!(solver.step(&ctx.device, &ctx.queue, 1e-12).is_err());
    let err = solver
        .advance(&ctx.device, &ctx.queue, 0.01, sph_gpu::MAX_BATCH + 1)
        .unwrap_err();
    assert!(err.to_string().contains("MAX_BATCH"), "{err}");

    // The density pass walks a hashed grid only, and encodes only its own.
    let boxed = GpuGrid::in_box(&ctx.device, 2, 0.1, 8, Vec3::ZERO, Vec3::splat(0.3)).unwrap();
    assert!(boxed.is_box());
    match sph_gpu::GpuDensity::new(&ctx.device, &boxed, 2, &params, &boundary, &[]) {
        Err(e) => assert!(e.to_string().contains("in_box"), "{e}"),
        Ok(_) => panic!("a density pass over a box grid"),
    }
    let mut density =
        sph_gpu::GpuDensity::new(&ctx.device, &grid, 2, &params, &boundary, &[]).unwrap();
    let other = GpuGrid::new(&ctx.device, 2, 0.1, 8).unwrap();
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    assert!(density.encode(&ctx.queue, &mut encoder, &other).is_err());
    density.encode(&ctx.queue, &mut encoder, &grid).unwrap();
}

#[test]
fn gpu_density_matches_the_cpu_processor() {
    use sph_core::processor::Processor;
    use sph_core::solver::{BuildGrid, DensityPressure};
    use sph_core::{Context, Scene};
    use sph_gpu::GpuDensity;

    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let scene = Scene::dam_break(0.2, 0.06, 0.02);
    let mut world = scene.build_world().unwrap();
    world.advance(0.3).unwrap();
    let (params, boundary) = (*world.params(), scene.boundary());
    let mut cpu = world.particles.clone();
    let mut c = Context::new(1e-3);
    BuildGrid::new(params.h, 0)
        .process(&mut cpu, &mut c)
        .unwrap();
    DensityPressure::new(params, boundary.clone())
        .unwrap()
        .process(&mut cpu, &mut c)
        .unwrap();

    let n = cpu.len();
    let mut grid = GpuGrid::new(&ctx.device, n, params.h, 1).unwrap();
    grid.upload_with_masses(&ctx.queue, cpu.positions(), Some(cpu.masses()))
        .unwrap();
    let mut density =
        GpuDensity::new(&ctx.device, &grid, n, &params, &boundary, cpu.masses()).unwrap();
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    grid.encode_build(&mut encoder);
    density.encode(&ctx.queue, &mut encoder, &grid).unwrap();
    ctx.queue.submit([encoder.finish()]);
    let (rho, p) = density.read(&ctx.device, &ctx.queue).unwrap();
    let mut worst = 0f32;
    for i in 0..n {
        let e = (rho[i] - cpu.densities()[i]).abs() / cpu.densities()[i];
        worst = worst.max(e);
        let dp = (p[i] - cpu.pressures()[i]).abs();
        assert!(
            dp <= 2e-5 * params.stiffness * params.rest_density,
            "pressure {i}: {} vs {}",
            p[i],
            cpu.pressures()[i]
        );
    }
    println!("{n} particles: worst relative density difference GPU vs CPU {worst:.2e}");
    assert!(worst < 5e-3, "worst relative density difference {worst}");
}

#[test]
fn hundred_gpu_steps_match_the_cpu_solver() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    hundred_steps(ctx, sph_core::Scene::dam_break(0.2, 0.06, 0.02), |_, _| {});
}

/// The thesis's spiky pressure gradient, with two particles at the same
/// point: both paths give coincident particles no pressure force from each
/// other (on the GPU that took a guard against 0/0).
#[test]
fn hundred_gpu_steps_with_spiky_pressure_and_a_duplicate_match_the_cpu_solver() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let scene = sph_core::Scene::dam_break(0.2, 0.06, 0.02);
    hundred_steps(ctx, scene, |particles, params| {
        params.pressure_kernel = sph_core::PressureKernel::Spiky;
        let (x, m) = (particles.positions()[7], particles.masses()[7]);
        particles.push(x, Vec3::ZERO, m);
    });
}

#[test]
fn hundred_gpu_steps_with_obstacles_match_the_cpu_solver() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    hundred_steps(ctx, with_obstacles(0.0), |_, _| {});
}

/// The projection keeps particle centres half a spacing from the walls and
/// obstacles on both paths.
#[test]
fn hundred_gpu_steps_with_a_clearance_match_the_cpu_solver() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    hundred_steps(ctx, with_obstacles(0.01), |_, _| {});
}

/// A dam break with a sphere inside its column and a box against it, and
/// particle centres kept `clearance` from every surface.
fn with_obstacles(clearance: f32) -> sph_core::Scene {
    use sph_core::scene::ObstacleSpec;
    let mut scene = sph_core::Scene::dam_break(0.2, 0.06, 0.02);
    scene.clearance = Some(clearance);
    // A sphere inside the column (its lattice points are left out) and a box
    // against the column's front: fluid is within h of both from the start.
    scene.obstacles = vec![
        ObstacleSpec::Sphere {
            centre: [0.1, 0.2, 0.03],
            radius: 0.05,
        },
        ObstacleSpec::Box {
            min: [0.2, 0.0, 0.0],
            max: [0.26, 0.06, 0.06],
        },
    ];
    scene
}

/// 100 steps of `scene` on both paths, its particles and parameters changed
/// by `adjust` first: positions within 1e-3 h, densities within 0.5 %.
fn hundred_steps(
    ctx: &GpuContext,
    scene: sph_core::Scene,
    adjust: impl FnOnce(&mut sph_core::Particles, &mut sph_core::FluidParams),
) {
    use sph_core::Context;
    use sph_core::processor::Processor;
    use sph_core::solver::{Boundaries, BuildGrid, DensityPressure, Forces, Integrate};
    use sph_gpu::GpuSolver;

    let world = scene.build_world().unwrap();
    let mut params = *world.params();
    params.surface_tension = 0.5; // exercise eq. 18–20 too
    let boundary = scene.boundary();
    // The solver's own stable step (CFL with c = √k) at the start.
    let dt = world.stable_dt();
    // The CPU reference without the grid's periodic reordering, so index i is
    // the same particle on both paths.
    let mut cpu = world.particles.clone();
    adjust(&mut cpu, &mut params);
    let start = cpu.clone();
    let mut program: Vec<Box<dyn Processor>> = vec![
        Box::new(BuildGrid::new(params.h, 0)),
        Box::new(DensityPressure::new(params, boundary.clone()).unwrap()),
        Box::new(Forces::new(params, boundary.clone()).unwrap()),
        Box::new(Integrate),
        Box::new(Boundaries::new(boundary.clone()).unwrap()),
    ];
    let mut gpu = GpuSolver::new(&ctx.device, &ctx.queue, &cpu, &params, &boundary).unwrap();
    for _ in 0..100 {
        let mut c = Context::new(dt);
        for p in &mut program {
            p.process(&mut cpu, &mut c).unwrap();
        }
        gpu.step(&ctx.device, &ctx.queue, dt).unwrap();
    }
    let state = gpu.read_state(&ctx.device, &ctx.queue).unwrap();
    // f32::max below would skip a NaN.
    assert!(
        state.positions.iter().all(|x| x.is_finite()),
        "a non-finite GPU position"
    );
    assert!(
        state.densities.iter().all(|r| r.is_finite()),
        "a non-finite GPU density"
    );
    let (mut dx, mut drho, mut moved) = (0f32, 0f32, 0f32);
    for i in 0..cpu.len() {
        dx = dx.max((state.positions[i] - cpu.positions()[i]).length());
        drho = drho.max((state.densities[i] - cpu.densities()[i]).abs() / cpu.densities()[i]);
        moved = moved.max((cpu.positions()[i] - start.positions()[i]).length());
    }
    println!(
        "{} ({} obstacles): {} particles, 100 steps of {dt} s: particles moved up to {moved:.4} m; GPU vs CPU: max |Δx| = {:.2e} h, max |Δρ|/ρ = {drho:.2e}",
        scene.name,
        boundary.obstacles.len(),
        cpu.len(),
        dx / params.h
    );
    assert!(moved > 0.1 * params.h, "the fluid hardly moved: {moved}");
    assert!(dx < 1e-3 * params.h, "positions differ by {dx} m");
    assert!(drho < 5e-3, "densities differ by {drho}");
}

/// The CPU world of `scene` and a GPU solver of the same particles,
/// parameters and time stepping.
fn world_and_gpu_solver(
    ctx: &GpuContext,
    scene: &sph_core::Scene,
) -> (sph_core::World, sph_gpu::GpuSolver) {
    let world = scene.build_world().unwrap();
    let mut gpu = sph_gpu::GpuSolver::new(
        &ctx.device,
        &ctx.queue,
        &world.particles,
        world.params(),
        &scene.boundary(),
    )
    .unwrap();
    gpu.set_time_stepping(world.time_stepping()).unwrap();
    (world, gpu)
}

#[test]
fn adaptive_gpu_frames_match_world_advance() {
    use sph_gpu::GpuError;
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let (mut world, mut gpu) =
        world_and_gpu_solver(ctx, &sph_core::Scene::dam_break(0.2, 0.06, 0.02));
    let (device, queue) = (&ctx.device, &ctx.queue);
    let h = world.params().h;
    let frame_dt = 1.0 / 60.0;
    // Batches of one step, of fewer steps than a frame takes, and of far more
    // (the steps past the frame's end must change nothing).
    for (frame, batch) in [8, 1, 64].into_iter().enumerate() {
        let cpu = world.advance(frame_dt).unwrap();
        let g = gpu.advance(device, queue, frame_dt, batch).unwrap();
        let state = gpu.read_state(device, queue).unwrap();
        // The world reorders its particles; ids are the original indices.
        let p = &world.particles;
        let dx = p
            .ids()
            .iter()
            .zip(p.positions())
            .map(|(&id, x)| (state.positions[id as usize] - *x).length())
            .fold(0f32, f32::max);
        println!(
            "frame {frame}, batch {batch}: {} CPU substeps, {} GPU substeps, GPU elapsed {:.6} s of {frame_dt:.6}, max |Δx| = {:.2e} h",
            cpu.substeps,
            g.substeps,
            g.elapsed,
            dx / h
        );
        assert_eq!(g.substeps, cpu.substeps, "frame {frame}");
        assert!((g.elapsed - frame_dt).abs() < 1e-6, "{}", g.elapsed);
        assert!(dx < 1e-3 * h, "frame {frame}: positions differ by {dx} m");
    }
    assert!(gpu.advance(device, queue, f32::NAN, 8).is_err());
    assert!(gpu.advance(device, queue, frame_dt, 0).is_err());
    // A blown-up particle stops the frame with an error, not a NaN state.
    queue.write_buffer(
        gpu.velocities_buffer(),
        0,
        bytemuck::cast_slice(&[f32::NAN, 0.0, f32::NAN, 0.0]),
    );
    let err = gpu.advance(device, queue, frame_dt, 8).unwrap_err();
    assert!(matches!(err, GpuError::Unstable(_)), "{err}");
}

/// A fluid viscous enough that the viscous step limit binds: the GPU takes
/// the CPU's substeps, and the particles stay together. (μ = 2900 Pa·s makes
/// the frame 241.7 limit steps long: a whole number of them would leave the
/// substep count to the last bit of the f32/f64 time sums.)
#[test]
fn viscous_gpu_frame_keeps_to_the_cpu_step_limit() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let mut scene = sph_core::Scene::dam_break(0.2, 0.06, 0.02);
    scene.fluid.viscosity = Some(2900.0);
    let (mut world, mut gpu) = world_and_gpu_solver(ctx, &scene);
    let (device, queue) = (&ctx.device, &ctx.queue);
    let frame_dt = 1.0 / 60.0;
    let cpu = world.advance(frame_dt).unwrap();
    let g = gpu.advance(device, queue, frame_dt, 64).unwrap();
    let limit = world.params().viscous_dt();
    println!(
        "μ = 2900 Pa·s: {} CPU substeps (longest {:e} s, limit {limit:e} s), {} GPU substeps",
        cpu.substeps, cpu.dt_range.1, g.substeps
    );
    assert!(cpu.dt_range.1 <= limit);
    assert_eq!(g.substeps, cpu.substeps);
    let state = gpu.read_state(device, queue).unwrap();
    let p = &world.particles;
    let dx = (p.ids().iter().zip(p.positions()))
        .map(|(&id, x)| (state.positions[id as usize] - *x).length())
        .fold(0f32, f32::max);
    assert!(dx < 1e-3 * world.params().h, "positions differ by {dx} m");
}

/// The `_profiled` variants time every pass and change nothing: a profiled
/// solver and a plain one of the same particles end a frame in bitwise the
/// same state, and the profile names each pass of every recorded step with
/// a finite, non-negative time.
#[test]
fn profiled_frames_time_every_pass_and_change_nothing() {
    use sph_gpu::wgpu_profiler::{GpuProfiler, GpuProfilerSettings};
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let scene = sph_core::Scene::dam_break(0.2, 0.06, 0.02);
    let (_, mut plain) = world_and_gpu_solver(ctx, &scene);
    let (_, mut timed) = world_and_gpu_solver(ctx, &scene);
    let (device, queue) = (&ctx.device, &ctx.queue);
    let mut profiler = GpuProfiler::new(device, GpuProfilerSettings::default()).unwrap();
    let frame_dt = 1.0 / 60.0;
    let batch = 8;
    let a = plain.advance(device, queue, frame_dt, batch).unwrap();
    let b = timed
        .advance_profiled(device, queue, frame_dt, batch, &profiler)
        .unwrap();
    assert_eq!(a, b);
    let (sa, sb) = (
        plain.read_state(device, queue).unwrap(),
        timed.read_state(device, queue).unwrap(),
    );
    assert_eq!(sa.positions, sb.positions);
    assert_eq!(sa.velocities, sb.velocities);
    assert_eq!(sa.densities, sb.densities);

    let mut encoder = device.create_command_encoder(&Default::default());
    profiler.resolve_queries(&mut encoder);
    queue.submit([encoder.finish()]);
    profiler.end_frame().unwrap();
    device
        .poll(splat_render::wgpu::PollType::wait_indefinitely())
        .unwrap();
    let results = profiler
        .process_finished_frame(queue.get_timestamp_period())
        .expect("the frame's queries are resolved");
    let passes = [
        "step length: reduce_max",
        "step length: choose_dt",
        "grid: clear_counts",
        "grid: count_cells",
        "grid: scan_blocks",
        "grid: scan_block_sums",
        "grid: add_block_sums",
        "grid: scatter",
        "grid: sort_buckets",
        "density",
        "forces",
        "integrate",
    ];
    // Each recorded step (the frame's, then those past its end) in order.
    let labels: Vec<&str> = results.iter().map(|r| r.label.as_str()).collect();
    assert_eq!(labels.len() % passes.len(), 0, "{labels:?}");
    let steps = labels.len() / passes.len();
    // Whole batches, the last one holding the frame's last substep.
    assert_eq!(
        steps,
        (b.substeps.div_ceil(batch) * batch) as usize,
        "{steps} steps recorded for {} substeps",
        b.substeps
    );
    for step in labels.chunks(passes.len()) {
        assert_eq!(step, passes);
    }
    let timestamps = device
        .features()
        .contains(splat_render::wgpu::Features::TIMESTAMP_QUERY);
    let mut total = 0.0;
    for r in &results {
        match (&r.time, timestamps) {
            (Some(t), true) => {
                assert!(t.end >= t.start, "{}: {t:?}", r.label);
                total += t.end - t.start;
            }
            (None, false) => {}
            (t, _) => panic!("{}: {t:?} with timestamps {timestamps}", r.label),
        }
    }
    println!(
        "{} substeps, {steps} steps recorded; timestamps: {timestamps}, GPU time of the passes {:.3} ms",
        b.substeps,
        total * 1e3
    );
    if timestamps {
        assert!(total > 0.0, "no GPU time at all");
    }
}

/// The GPU's largest-speed reduction sees every particle: one fast particle,
/// in turn the first and the last lane of a workgroup and the last particle,
/// shortens the GPU's first step as it does the CPU's. The frame lies
/// between the two stable steps, so it takes one step without the fast
/// particle and two with it, before the particle can reach a wall.
#[test]
fn one_fast_particle_in_any_lane_sets_the_gpu_step() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let (device, queue) = (&ctx.device, &ctx.queue);
    let scene = sph_core::Scene::dam_break(0.2, 0.06, 0.02);
    let calm = scene.build_world().unwrap();
    let n = calm.particles.len();
    assert!(n > 200, "{n} particles");
    let fast = Vec3::new(0.0, 0.0, 40.0);
    for i in [64, 127, n - 1] {
        let (mut world, mut gpu) = world_and_gpu_solver(ctx, &scene);
        world.particles.velocities_mut()[i] = fast;
        let (slow_dt, fast_dt) = (calm.stable_dt(), world.stable_dt());
        assert!(fast_dt < 0.75 * slow_dt, "{fast_dt} vs {slow_dt}");
        let frame_dt = 0.5 * (fast_dt + slow_dt);
        queue.write_buffer(
            gpu.velocities_buffer(),
            16 * i as u64,
            bytemuck::cast_slice(&[fast.x, fast.y, fast.z, 0.0]),
        );
        let cpu = world.advance(frame_dt).unwrap();
        let g = gpu.advance(device, queue, frame_dt, 4).unwrap();
        println!(
            "fast particle {i}: stable steps {fast_dt:.2e} / {slow_dt:.2e} s, frame {frame_dt:.2e} s: {} CPU substeps, {} GPU",
            cpu.substeps, g.substeps
        );
        assert_eq!(cpu.substeps, 2, "particle {i}");
        assert_eq!(
            g.substeps, 2,
            "particle {i}: the GPU missed the fast particle"
        );
    }
}

/// The demo's push (a `RayPush`) acts on WCSPH on the GPU as the push
/// processor after the forces does on the CPU: 50 steps of the dam break
/// pushed through its column agree within 1e-3 h, and differ from the
/// unpushed steps.
#[test]
fn a_push_acts_on_the_gpu_as_on_the_cpu() {
    use sph_core::Context;
    use sph_core::processor::Processor;
    use sph_core::solver::{
        Boundaries, BuildGrid, DensityPressure, ExternalAcceleration, Forces, Integrate,
    };
    use sph_gpu::{GpuSolver, RayPush};
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let scene = sph_core::Scene::dam_break(0.2, 0.06, 0.02);
    let world = scene.build_world().unwrap();
    let params = *world.params();
    let boundary = scene.boundary();
    let dt = world.stable_dt();
    let push = RayPush {
        origin: Vec3::new(0.1, 0.2, 0.0),
        dir: Vec3::Z,
        acceleration: Vec3::new(30.0, 5.0, 0.0),
        radius: 4.0 * params.h,
    };
    let mut cpu = world.particles.clone();
    let mut program: Vec<Box<dyn Processor>> = vec![
        Box::new(BuildGrid::new(params.h, 0)),
        Box::new(DensityPressure::new(params, boundary.clone()).unwrap()),
        Box::new(Forces::new(params, boundary.clone()).unwrap()),
        Box::new(ExternalAcceleration::new("push", move |x, _| {
            push.acceleration_at(x)
        })),
        Box::new(Integrate),
        Box::new(Boundaries::new(boundary.clone()).unwrap()),
    ];
    let gpu_steps = |push: Option<RayPush>| {
        let mut gpu = GpuSolver::new(&ctx.device, &ctx.queue, &cpu, &params, &boundary).unwrap();
        gpu.set_push(push).unwrap();
        for _ in 0..50 {
            gpu.step(&ctx.device, &ctx.queue, dt).unwrap();
        }
        gpu.read_state(&ctx.device, &ctx.queue).unwrap().positions
    };
    let (pushed, unpushed) = (gpu_steps(Some(push)), gpu_steps(None));
    for _ in 0..50 {
        let mut c = Context::new(dt);
        for p in &mut program {
            p.process(&mut cpu, &mut c).unwrap();
        }
    }
    let offset = |a: &[Vec3]| {
        a.iter()
            .zip(cpu.positions())
            .map(|(g, c)| (*g - *c).length())
            .fold(0.0f32, f32::max)
            / params.h
    };
    let (dx, moved) = (offset(&pushed), offset(&unpushed));
    println!("50 pushed WCSPH steps: GPU vs CPU {dx:.2e} h; against unpushed {moved:.3} h");
    assert!(dx < 1e-3, "positions differ by {dx} h");
    assert!(moved > 0.01, "the push hardly moved the fluid: {moved} h");
}
