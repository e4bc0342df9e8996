//! Position-based fluids on the GPU (`GpuPbf`) against sph-core's PBF
//! stations on the CPU: the same particles after whole frames, the same
//! frame statistics, bitwise the same result on every run, and clear errors.
//! On lavapipe in CI; skipped without an adapter unless `SPH_REQUIRE_GPU=1`.

use glam::Vec3;
use sph_core::processor::Processor;
use sph_core::solver::pbf::{Predict, SolveDensity, VorticityXsph};
use sph_core::solver::{BodyForces, Boundaries, BuildGrid, FindNeighbours};
use sph_core::{Context, Particles, PbfParams, Scene};
use sph_gpu::{GpuError, GpuPbf, MAX_NEIGHBOURS};
use splat_render::GpuContext;

/// A dam break with a sphere inside its column and a box against it, and
/// particle centres kept `clearance` from every surface.
fn with_obstacles(clearance: f32) -> Scene {
    use sph_core::scene::ObstacleSpec;
    let mut scene = Scene::dam_break(0.2, 0.06, 0.02).with_solver(sph_core::SolverKind::Pbf);
    scene.clearance = Some(clearance);
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

/// The CPU's PBF program station by station, without the grid's reordering,
/// so that index i is the same particle on both paths.
fn cpu_program(scene: &Scene, pbf: PbfParams) -> Vec<Box<dyn Processor>> {
    let params = scene.fluid_params();
    let boundary = scene.boundary();
    vec![
        Box::new(BodyForces::new(params.gravity)),
        Box::new(Predict::new(boundary.clone(), pbf.max_displacement * params.h).unwrap()),
        Box::new(BuildGrid::new(params.h, 0)),
        Box::new(FindNeighbours::new(params.h)),
        Box::new(SolveDensity::new(params, pbf, boundary.clone()).unwrap()),
        Box::new(VorticityXsph::new(params, pbf, boundary.clone()).unwrap()),
        Box::new(Boundaries::new(boundary).unwrap()),
    ]
}

/// Advances `particles` by `frames` frames of `frame_dt` on the CPU and
/// returns how many particles the guard clamped.
fn cpu_frames(
    program: &mut [Box<dyn Processor>],
    particles: &mut Particles,
    pbf: &PbfParams,
    frames: u32,
    frame_dt: f32,
) -> u64 {
    let substeps = pbf.substeps_for(frame_dt);
    let dt = frame_dt / substeps as f32;
    let mut clamped = 0;
    for _ in 0..frames * substeps {
        let mut ctx = Context::new(dt);
        for p in program.iter_mut() {
            p.process(particles, &mut ctx).unwrap();
        }
        clamped += ctx.counters.clamped;
    }
    clamped
}

/// The positions the world's particles start at.
fn start_positions(world: &sph_core::World) -> Vec<Vec3> {
    world.particles.positions().to_vec()
}

/// A GPU solver of `particles` in `scene` (its fluid and walls) with `pbf`.
fn gpu_pbf(ctx: &GpuContext, scene: &Scene, particles: &Particles, pbf: &PbfParams) -> GpuPbf {
    GpuPbf::new(
        &ctx.device,
        &ctx.queue,
        particles,
        &scene.fluid_params(),
        pbf,
        &scene.boundary(),
    )
    .unwrap()
}

/// The largest distance between the two paths' particles, over h.
fn max_offset(gpu: &[Vec3], cpu: &Particles, h: f32) -> f32 {
    gpu.iter()
        .zip(cpu.positions())
        .map(|(g, c)| (*g - *c).length())
        .fold(0.0, f32::max)
        / h
}

/// Two frames of 1/60 s (6 substeps of 3 iterations, s_corr, vorticity
/// confinement and XSPH on) of a swirling dam break around a sphere and a
/// box with a clearance: the GPU's particles stay within 1e-3 h of the
/// CPU's (1e-4 h measured), its velocities, densities and pressures as
/// close, while the
/// fluid moves several h. (The two differ by rounding alone: the CPU sums
/// eight lanes at a time in another order. Left to run, rounding grows
/// through the chaotic flow: 2 % of h after four frames of the column's
/// fall.)
#[test]
fn gpu_pbf_frames_match_the_cpu_stations() {
    const FRAMES: u32 = 1;
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let scene = with_obstacles(0.01);
    let pbf = PbfParams {
        scorr_k: 0.001,
        vorticity: 0.1,
        xsph: 0.05,
        ..scene.pbf_params()
    };
    let world = scene.build_world().unwrap();
    let h = world.params().h;
    let mut cpu = world.particles.clone();
    // A swirl about the column's axis, up to 9 m/s: the fluid meets the
    // walls, the sphere and the box within the frames, and the fastest
    // particles meet the displacement guard.
    let axis = Vec3::new(0.1, 0.2, 0.03);
    for (v, x) in cpu
        .fields_mut()
        .velocities
        .iter_mut()
        .zip(start_positions(&world))
    {
        *v = Vec3::new(0.0, 0.0, 35.0).cross(x - axis) + Vec3::new(0.5, -1.0, 0.2);
    }
    let start = cpu.clone();
    let fastest = cpu
        .velocities()
        .iter()
        .map(|v| v.length())
        .fold(0.0, f32::max);
    let mut program = cpu_program(&scene, pbf);
    let mut gpu = gpu_pbf(ctx, &scene, &cpu, &pbf);
    let frame_dt = 1.0 / 60.0;
    let mut clamped = 0;
    for _ in 0..FRAMES {
        let frame = gpu.advance(&ctx.device, &ctx.queue, frame_dt).unwrap();
        clamped += frame.stats.iter().map(|s| s.clamped).sum::<u64>();
    }
    clamped += gpu
        .finish(&ctx.device)
        .unwrap()
        .iter()
        .map(|s| s.clamped)
        .sum::<u64>();
    let cpu_clamped = cpu_frames(&mut program, &mut cpu, &pbf, FRAMES, frame_dt);
    let state = gpu.read_state(&ctx.device, &ctx.queue).unwrap();
    assert!(state.positions.iter().all(|x| x.is_finite()));
    let dx = max_offset(&state.positions, &cpu, h);
    let moved = max_offset(start.positions(), &cpu, h);
    let drho = (state.densities.iter().zip(cpu.densities()))
        .map(|(g, c)| (g - c).abs() / c)
        .fold(0.0, f32::max);
    let dv = (state.velocities.iter().zip(cpu.velocities()))
        .map(|(g, c)| (*g - *c).length())
        .fold(0.0, f32::max);
    let dp = (state.pressures.iter().zip(cpu.pressures()))
        .map(|(g, c)| (g - c).abs())
        .fold(0.0, f32::max);
    let p_max = cpu.pressures().iter().fold(0.0f32, |m, p| m.max(p.abs()));
    println!(
        "{} particles, {FRAMES} frames: moved up to {moved:.2} h, {clamped} clamped (from up to {fastest:.1} m/s); GPU vs CPU: |Δx| ≤ {dx:.2e} h, \
         |Δv| ≤ {dv:.2e} m/s, |Δρ|/ρ ≤ {drho:.2e}, |Δp| ≤ {dp:.2e} of {p_max:.1} Pa",
        cpu.len()
    );
    assert!(moved > 2.0, "the fluid hardly moved: {moved} h");
    assert!(clamped > 0, "the guard never acted");
    assert_eq!(clamped, cpu_clamped, "particles clamped");
    assert!(dx < 1e-3, "positions differ by {dx} h");
    assert!(drho < 5e-4, "densities differ by {drho}");
    assert!(dv < 3e-3, "velocities differ by {dv} m/s");
    assert!(dp < 1e-3 * p_max, "pressures differ by {dp} Pa");
}

/// The statistics of a frame come back with a later frame, and match the CPU
/// world's report of the same frame.
#[test]
fn gpu_pbf_statistics_come_back_a_frame_late_and_match_the_cpu_report() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let scene = Scene::dam_break(0.2, 0.06, 0.02).with_solver(sph_core::SolverKind::Pbf);
    let mut world = scene.build_world().unwrap();
    let pbf = scene.pbf_params();
    let mut gpu = gpu_pbf(ctx, &scene, &world.particles, &pbf);
    let frame_dt = 1.0 / 60.0;
    let mut reports = Vec::new();
    let mut stats = Vec::new();
    for _ in 0..6 {
        reports.push(world.advance(frame_dt).unwrap());
        let frame = gpu.advance(&ctx.device, &ctx.queue, frame_dt).unwrap();
        assert_eq!(frame.substeps, reports.last().unwrap().substeps);
        assert_eq!(frame.iterations, reports.last().unwrap().iterations);
        for s in frame.stats {
            // Never this frame's: it was only just recorded.
            assert!(
                s.frame + 1 < gpu.frames(),
                "frame {} came back at once",
                s.frame
            );
            stats.push(s);
        }
    }
    stats.extend(gpu.finish(&ctx.device).unwrap());
    let frames: Vec<u64> = stats.iter().map(|s| s.frame).collect();
    assert_eq!(
        frames,
        (0..6).collect::<Vec<_>>(),
        "every frame's statistics, in order"
    );
    for s in &stats {
        let cpu = &reports[s.frame as usize];
        println!(
            "frame {}: density error avg {:.4} % (CPU {:.4} %), max {:.3} % (CPU {:.3} %), \
             clamped {} (CPU {}), up to {} neighbours",
            s.frame,
            100.0 * s.density_error_avg,
            100.0 * cpu.density_error_avg,
            100.0 * s.density_error_max,
            100.0 * cpu.density_error_max,
            s.clamped,
            cpu.clamped,
            s.most_neighbours
        );
        assert_eq!(s.substeps, cpu.substeps);
        assert_eq!(s.clamped, cpu.clamped);
        let close = |a: f32, b: f32| (a - b).abs() <= 0.02 * b.abs() + 1e-5;
        assert!(
            close(s.density_error_avg, cpu.density_error_avg),
            "frame {}: average error {} against {}",
            s.frame,
            s.density_error_avg,
            cpu.density_error_avg
        );
        assert!(
            close(s.density_error_max, cpu.density_error_max),
            "frame {}: largest error {} against {}",
            s.frame,
            s.density_error_max,
            cpu.density_error_max
        );
        assert!((20..=MAX_NEIGHBOURS).contains(&s.most_neighbours));
    }
    assert!(
        stats.iter().any(|s| s.density_error_avg > 1e-4),
        "the column never compressed"
    );
}

/// Two runs from the same particles give bitwise the same state.
#[test]
fn gpu_pbf_is_deterministic() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let scene = with_obstacles(0.0);
    let world = scene.build_world().unwrap();
    let run = || {
        let mut gpu = gpu_pbf(ctx, &scene, &world.particles, &scene.pbf_params());
        for _ in 0..3 {
            gpu.advance(&ctx.device, &ctx.queue, 1.0 / 60.0).unwrap();
        }
        let stats = *gpu.finish(&ctx.device).unwrap().last().unwrap();
        let state = gpu.read_state(&ctx.device, &ctx.queue).unwrap();
        let bits = |v: &[Vec3]| -> Vec<u32> {
            v.iter()
                .flat_map(|v| v.to_array().map(f32::to_bits))
                .collect()
        };
        (
            bits(&state.positions),
            bits(&state.velocities),
            stats.density_error_avg.to_bits(),
        )
    };
    let first = run();
    assert!(first == run(), "a second run differs");
}

/// Parameters the GPU cannot run, and states it cannot step, are errors that
/// say why.
#[test]
fn gpu_pbf_refuses_what_it_cannot_run() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let scene = Scene::dam_break(0.2, 0.06, 0.02).with_solver(sph_core::SolverKind::Pbf);
    let world = scene.build_world().unwrap();
    let new = |params: &sph_core::FluidParams, pbf: &PbfParams, particles: &Particles| {
        GpuPbf::new(
            &ctx.device,
            &ctx.queue,
            particles,
            params,
            pbf,
            &scene.boundary(),
        )
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default()
    };
    let (params, pbf) = (*world.params(), scene.pbf_params());
    let implicit = PbfParams {
        viscosity: sph_core::PbfViscosity::Implicit,
        ..pbf
    };
    let e = new(&params, &implicit, &world.particles);
    assert!(e.contains("implicit") && e.contains("CPU"), "{e}");
    let sleeping = PbfParams {
        sleep_speed: 0.01,
        ..pbf
    };
    let e = new(&params, &sleeping, &world.particles);
    assert!(e.contains("sleep_speed") && e.contains("CPU"), "{e}");
    let gauss_seidel = PbfParams {
        solve: sph_core::PbfSolve::GaussSeidel,
        ..pbf
    };
    let e = new(&params, &gauss_seidel, &world.particles);
    assert!(e.contains("gauss-seidel") && e.contains("CPU"), "{e}");
    // σ by the thesis's colour field is WCSPH's only, on the GPU as on the
    // CPU (Akinci et al.'s forces, the default, run).
    let colour_field = sph_core::FluidParams {
        surface_tension: 0.07,
        surface_tension_model: Some(sph_core::SurfaceTensionModel::ColourField),
        ..params
    };
    let e = new(&colour_field, &pbf, &world.particles);
    assert!(e.contains("surface_tension_model"), "{e}");
    let zero = PbfParams {
        iterations: 0,
        ..pbf
    };
    let e = new(&params, &zero, &world.particles);
    assert!(e.contains("pbf.iterations"), "{e}");
    // h = 3.2 spacings, which the CPU runs: 136 neighbours at rest would
    // overflow the lists; refused at once, not frames later. 2.4 runs.
    for (spacing, refused) in [(0.0125f32, true), (0.04 / 2.4, false)] {
        let mut wide = Scene::dam_break(0.1, 0.06, spacing).with_solver(sph_core::SolverKind::Pbf);
        wide.fluid.h = 0.04;
        let wide = wide.build_world().unwrap();
        let e = new(wide.params(), &pbf, &wide.particles);
        if refused {
            assert!(e.contains("neighbours") && e.contains("--cpu"), "{e}");
        } else {
            assert_eq!(e, "", "h = 2.4 spacings");
        }
    }
    // A domain 2^20 h out, where f32 resolves positions to h/8.
    let b = scene.boundary();
    let offset = glam::Vec3::X * (1_048_576.0 * params.h);
    let far = sph_core::Boundary::new(sph_core::Aabb::new(
        b.domain.min + offset,
        b.domain.max + offset,
    ));
    let e = GpuPbf::new(
        &ctx.device,
        &ctx.queue,
        &world.particles,
        &params,
        &pbf,
        &far,
    )
    .err()
    .map(|e| e.to_string())
    .unwrap_or_default();
    assert!(e.contains("domain") && e.contains("65,536 h"), "{e}");
    let mut gpu = GpuPbf::new(
        &ctx.device,
        &ctx.queue,
        &world.particles,
        &params,
        &pbf,
        &scene.boundary(),
    )
    .unwrap();
    // A frame below sph-core's min_dt, the CPU's shortest step, as well.
    assert_eq!(
        sph_gpu::MIN_FRAME_DT,
        sph_core::TimeStepping::default().min_dt
    );
    for bad in [0.0, -1.0, f32::NAN, f32::INFINITY, 1e-9] {
        assert!(matches!(
            gpu.advance(&ctx.device, &ctx.queue, bad),
            Err(GpuError::Invalid(_))
        ));
    }
    // A frame of more than 1000 substeps of max_dt, as on the CPU.
    match gpu.advance(&ctx.device, &ctx.queue, 10.0) {
        Err(GpuError::Params(e)) => assert!(e.to_string().contains("pbf.max_dt"), "{e}"),
        other => panic!("{:?}", other.err()),
    }

    // 200 particles on one point: more neighbours than a list holds.
    let mut heap = Particles::new();
    for _ in 0..200 {
        heap.push(
            Vec3::new(0.1, 0.1, 0.03),
            Vec3::ZERO,
            world.particles.masses()[0],
        );
    }
    let mut gpu = GpuPbf::new(
        &ctx.device,
        &ctx.queue,
        &heap,
        &params,
        &pbf,
        &scene.boundary(),
    )
    .unwrap();
    let mut result = Ok(Vec::new());
    for _ in 0..3 {
        if let Err(e) = gpu.advance(&ctx.device, &ctx.queue, 1.0 / 60.0) {
            result = Err(e);
            break;
        }
    }
    if result.is_ok() {
        result = gpu.finish(&ctx.device);
    }
    let e = result
        .expect_err("a heap of 200 particles on one point")
        .to_string();
    println!("{e}");
    assert!(e.contains("neighbours") || e.contains("diverged"), "{e}");
}

/// A profiled frame gives bitwise the same state as a plain one, and its
/// profile names every pass of every substep and iteration, in order, with
/// a finite, non-negative time.
#[test]
fn gpu_pbf_profiled_frames_time_every_pass_and_change_nothing() {
    use sph_gpu::wgpu_profiler::{GpuProfiler, GpuProfilerSettings};
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let scene = Scene::dam_break(0.2, 0.06, 0.02).with_solver(sph_core::SolverKind::Pbf);
    let world = scene.build_world().unwrap();
    let pbf = scene.pbf_params();
    let (device, queue) = (&ctx.device, &ctx.queue);
    let new = || gpu_pbf(ctx, &scene, &world.particles, &pbf);
    let (mut plain, mut timed) = (new(), new());
    let mut profiler = GpuProfiler::new(device, GpuProfilerSettings::default()).unwrap();
    let frame_dt = 1.0 / 60.0;
    let a = plain.advance(device, queue, frame_dt).unwrap();
    let mut encoder = device.create_command_encoder(&Default::default());
    let b = timed
        .encode_frame_profiled(device, queue, &mut encoder, frame_dt, &profiler)
        .unwrap();
    profiler.resolve_queries(&mut encoder);
    queue.submit([encoder.finish()]);
    profiler.end_frame().unwrap();
    assert_eq!(a, b);
    let (sa, sb) = (
        plain.read_state(device, queue).unwrap(),
        timed.read_state(device, queue).unwrap(),
    );
    assert_eq!(sa.positions, sb.positions);
    assert_eq!(sa.velocities, sb.velocities);
    assert_eq!(sa.densities, sb.densities);
    assert_eq!(plain.finish(device).unwrap(), timed.finish(device).unwrap());

    let results = profiler
        .process_finished_frame(queue.get_timestamp_period())
        .expect("the frame's queries are resolved");
    let mut substep = vec!["pbf: predict", "pbf: grid", "pbf: gather", "pbf: lists"];
    for _ in 0..pbf.iterations {
        substep.extend(["pbf: lambda", "pbf: correct", "pbf: apply"]);
    }
    substep.extend([
        "pbf: curl",
        "pbf: confine",
        "pbf: boundaries",
        "pbf: scatter",
        "pbf: reduce",
    ]);
    let labels: Vec<&str> = results.iter().map(|r| r.label.as_str()).collect();
    assert_eq!(labels[0], "pbf: open gate");
    let labels = &labels[1..];
    assert_eq!(
        labels.len(),
        b.substeps as usize * substep.len(),
        "{labels:?}"
    );
    for step in labels.chunks(substep.len()) {
        assert_eq!(step, substep);
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
        "{} substeps, {} passes; timestamps: {timestamps}, GPU time of the passes {:.3} ms",
        b.substeps,
        labels.len(),
        total * 1e3
    );
    if timestamps {
        assert!(total > 0.0, "no GPU time at all");
    }
}

/// A scene too large for the device's storage bindings is an error naming
/// the limit, before any work: a device whose bindings hold 1 MiB, where a
/// particle's neighbour list alone takes 384 bytes.
#[test]
fn gpu_pbf_past_the_device_limits_is_an_error_naming_them() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let mut limits = ctx.adapter.limits();
    limits.max_storage_buffer_binding_size = 1 << 20;
    let (device, queue) = pollster::block_on(ctx.adapter.request_device(
        &splat_render::wgpu::DeviceDescriptor {
            label: Some("small bindings"),
            required_limits: limits,
            ..Default::default()
        },
    ))
    .expect("a device with smaller limits");
    let scene = Scene::dam_break(0.2, 0.06, 0.01).with_solver(sph_core::SolverKind::Pbf);
    let world = scene.build_world().unwrap();
    let n = world.particles.len();
    assert!(
        n * 4 * MAX_NEIGHBOURS as usize > 1 << 20,
        "{n} particles fit"
    );
    let e = GpuPbf::new(
        &device,
        &queue,
        &world.particles,
        world.params(),
        &scene.pbf_params(),
        &scene.boundary(),
    )
    .err()
    .expect("too many particles for 1 MiB bindings");
    println!("{e}");
    assert!(matches!(e, GpuError::DeviceLimit(_)), "{e}");
    let e = e.to_string();
    assert!(
        e.contains("1048576-byte storage bindings") && e.contains(&n.to_string()),
        "{e}"
    );
}

/// Two frames recorded into one encoder before one submission each run
/// with their own substep: the state is bitwise that of two frames
/// submitted one by one, the second frame twice as long as the first.
#[test]
fn gpu_pbf_frames_recorded_before_one_submission_keep_their_own_step() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let scene = Scene::dam_break(0.2, 0.06, 0.02).with_solver(sph_core::SolverKind::Pbf);
    let world = scene.build_world().unwrap();
    let (device, queue) = (&ctx.device, &ctx.queue);
    let new = || gpu_pbf(ctx, &scene, &world.particles, &scene.pbf_params());
    let (short, long) = (1.0 / 120.0, 1.0 / 60.0);
    let mut apart = new();
    apart.advance(device, queue, short).unwrap();
    apart.advance(device, queue, long).unwrap();
    let mut together = new();
    let mut encoder = device.create_command_encoder(&Default::default());
    let a = together
        .encode_frame(device, queue, &mut encoder, short)
        .unwrap();
    let b = together
        .encode_frame(device, queue, &mut encoder, long)
        .unwrap();
    queue.submit([encoder.finish()]);
    assert!(a.substeps != b.substeps || short != long);
    let (x, y) = (
        apart.read_state(device, queue).unwrap(),
        together.read_state(device, queue).unwrap(),
    );
    assert_eq!(x.positions, y.positions);
    assert_eq!(x.velocities, y.velocities);
    let (s, t) = (
        apart.finish(device).unwrap(),
        together.finish(device).unwrap(),
    );
    assert_eq!(t.len(), 2, "both frames' statistics");
    assert_eq!(s.last(), t.last());
}

/// A substep whose solve fails closes the gate: the rest of the frame
/// dispatches nothing, so the state is the failed substep's, bitwise that
/// of a solver that took only that substep.
#[test]
fn gpu_pbf_stops_at_the_substep_that_failed() {
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let scene = Scene::dam_break(0.2, 0.06, 0.02).with_solver(sph_core::SolverKind::Pbf);
    let world = scene.build_world().unwrap();
    // A heap on one point: the first substep's solve makes no headway.
    let mut heap = Particles::new();
    for _ in 0..200 {
        heap.push(
            Vec3::new(0.1, 0.1, 0.03),
            Vec3::ZERO,
            world.particles.masses()[0],
        );
    }
    let dt = 1.0 / 180.0;
    let run = |substeps: u32| {
        let pbf = PbfParams {
            substeps,
            max_dt: dt,
            ..scene.pbf_params()
        };
        let mut gpu = gpu_pbf(ctx, &scene, &heap, &pbf);
        gpu.advance(&ctx.device, &ctx.queue, substeps as f32 * dt)
            .unwrap();
        let failure = gpu.finish(&ctx.device).expect_err("the heap's solve fails");
        let state = gpu.read_state(&ctx.device, &ctx.queue).unwrap();
        (failure.to_string(), state.positions)
    };
    let (one, after_one) = run(1);
    let (three, after_three) = run(3);
    println!("{three}");
    assert!(
        one.contains("substep 0") && three.contains("substep 0"),
        "{three}"
    );
    assert!(
        after_one == after_three,
        "the two substeps after the failed one moved the particles"
    );
}

/// A push (the demo's Ctrl+drag) acts on the GPU as on the CPU: a frame of
/// the dam break pushed sideways through its column matches the CPU
/// stations with the same `RayPush` field after the body forces, and moves
/// the fluid away from where it goes unpushed.
#[test]
fn gpu_pbf_push_matches_the_cpu_push() {
    use sph_core::solver::ExternalAcceleration;
    use sph_gpu::RayPush;
    let Some(ctx) = GpuContext::headless_or_skip() else {
        return;
    };
    let scene = Scene::dam_break(0.2, 0.06, 0.02).with_solver(sph_core::SolverKind::Pbf);
    let world = scene.build_world().unwrap();
    let h = world.params().h;
    let pbf = scene.pbf_params();
    let push = RayPush {
        origin: Vec3::new(0.1, 0.2, 0.0),
        dir: Vec3::Z,
        acceleration: Vec3::new(30.0, 5.0, 0.0),
        radius: 4.0 * h,
    };
    let gpu_frame = |push: Option<RayPush>| {
        let mut gpu = gpu_pbf(ctx, &scene, &world.particles, &pbf);
        gpu.set_push(push).unwrap();
        gpu.advance(&ctx.device, &ctx.queue, 1.0 / 60.0).unwrap();
        gpu.read_state(&ctx.device, &ctx.queue).unwrap().positions
    };
    let (pushed, unpushed) = (gpu_frame(Some(push)), gpu_frame(None));
    let mut cpu = world.particles.clone();
    let mut program = cpu_program(&scene, pbf);
    program.insert(
        1,
        Box::new(ExternalAcceleration::new("push", move |x, _| {
            push.acceleration_at(x)
        })),
    );
    cpu_frames(&mut program, &mut cpu, &pbf, 1, 1.0 / 60.0);
    let dx = max_offset(&pushed, &cpu, h);
    let moved = max_offset(&unpushed, &cpu, h);
    println!("pushed frame: GPU vs CPU {dx:.2e} h; against the unpushed frame {moved:.3} h");
    assert!(dx < 1e-3, "positions differ by {dx} h");
    assert!(moved > 0.05, "the push hardly moved the fluid: {moved} h");
    // Bad pushes are errors.
    let mut gpu = gpu_pbf(ctx, &scene, &world.particles, &pbf);
    for bad in [
        RayPush {
            radius: 0.0,
            ..push
        },
        RayPush {
            dir: Vec3::new(1.0, 1.0, 0.0),
            ..push
        },
        RayPush {
            origin: Vec3::NAN,
            ..push
        },
    ] {
        assert!(matches!(gpu.set_push(Some(bad)), Err(GpuError::Invalid(_))));
    }
}
