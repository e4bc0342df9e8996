//! Divergence-free SPH against physics: a hydrostatic tank (density error,
//! pressure against the weight above, rest), the dam break's compression,
//! determinism across threads, and bad input.

mod common;

use sph_core::glam::Vec3;
use sph_core::{DfsphParams, Error, FluidParams, Particles, Scene, Solver, SolverKind, World};

/// A tank `w` × `w` across, filled to `depth` on a lattice of 0.02 m
/// (h = 0.04 m, μ = 0.5 Pa·s: the dam-break scene's fluid), run by DFSPH.
fn tank(w: f32, depth: f32, dfsph: DfsphParams) -> Scene {
    let mut scene = Scene::dam_break(w, w, 0.02).with_solver(SolverKind::Dfsph);
    scene.domain.max = [w, depth + 0.1, w];
    scene.blocks[0].max = [w, depth, w];
    scene.solver.dfsph = Some(dfsph);
    scene
}

/// Positions in the order of the particles' ids (the grid reorders them).
fn positions_by_id(p: &Particles) -> Vec<Vec3> {
    let mut pairs: Vec<_> = p.ids().iter().zip(p.positions()).collect();
    pairs.sort_by_key(|(id, _)| **id);
    pairs.into_iter().map(|(_, &x)| x).collect()
}

fn rms_speed(p: &Particles) -> f32 {
    let sum: f64 = p
        .velocities()
        .iter()
        .map(|v| f64::from(v.length_squared()))
        .sum();
    (sum / p.len() as f64).sqrt() as f32
}

/// Whether every particle is inside the domain and out of the obstacles.
fn contained(world: &World, scene: &Scene) -> bool {
    let boundary = scene.boundary();
    world
        .particles
        .positions()
        .iter()
        .all(|&x| boundary.admits(x))
}

/// A tank at rest, 0.48 m square and 0.2 m deep (5,760 particles), from the
/// second second on: the density error, the pressure against the weight of
/// the fluid above, rest.
///
/// The pressure is read where the walls do not disturb it: beyond 2h from
/// the floor and the side walls, h below the top layer
/// ([`common::pressures_and_weights_above`]). The walls push with the
/// particle's own κ only (the gradient of their density term, the force
/// that neither adds nor takes energy: see `sph_core::boundary`), so
/// without a clearance the layer on the floor holds about twice the
/// weight above it and the next one less; with a clearance of half a
/// spacing every layer's pressure is within 4 % of its weight above. Over
/// height, the same pressures' slope reads 2–4 % steep or shallow,
/// depending on how much of the surface's closer layers a fit takes in
/// (`docs/benchmark-notes.md`, "The hydrostatic tank against the weight
/// above").
///
/// The first steps settle the lattice by under a millimetre into the
/// edges and corners, where the walls' union formula leaves 0.3–0.8 % of
/// density missing; the slosh this starts decays under μ = 0.5 Pa·s.
#[test]
fn hydrostatic_tank() {
    let (w, depth) = (0.48, 0.2);
    let scene = tank(w, depth, DfsphParams::default());
    let mut world = scene.build_world().unwrap();
    let n = world.particles.len();
    let (mut worst_avg, mut worst_max, mut unconverged) = (0.0f32, 0.0f32, 0);
    let (mut rms_at_2s, mut at_3s) = (f32::NAN, Vec::new());
    for frame in 0..240 {
        let r = world.advance(1.0 / 60.0).unwrap();
        if frame == 119 {
            rms_at_2s = rms_speed(&world.particles);
        }
        if frame == 179 {
            at_3s = positions_by_id(&world.particles);
        }
        assert_eq!(r.solver, SolverKind::Dfsph);
        if frame >= 60 {
            worst_avg = worst_avg.max(r.density_error_avg);
            worst_max = worst_max.max(r.density_error_max);
            unconverged += r.unconverged;
        }
    }
    // The pressure of the particles more than 2h from the side walls and
    // the floor and h below the surface against the weight above them, at
    // every step of another half second (a Jacobi solve stopped at its
    // tolerance leaves each step's pressure some % off, and the steps'
    // errors alternate; their average holds).
    let h = scene.fluid.h;
    let mut samples = Vec::new();
    let end = world.time() + 0.5;
    while world.time() < end {
        world.step().unwrap();
        let p = &world.particles;
        samples.extend(common::pressures_and_weights_above(
            p,
            9.81,
            w,
            scene.spacing,
            h,
            2.0 * h,
        ));
    }
    let s = common::slope(samples.iter().copied());
    let rms = rms_speed(&world.particles);
    // The net drift from 3 s to the end (4.5 s).
    let drift = (positions_by_id(&world.particles).iter().zip(&at_3s))
        .map(|(a, b)| f64::from(a.distance_squared(*b)))
        .sum::<f64>();
    let drift = (drift / n as f64).sqrt();
    println!(
        "{n} particles, from 1 s: density error ≤ {:.4} % avg, ≤ {:.3} % max, {unconverged} unconverged; \
         pressure over the weight above {s:.4} over {} samples; \
         rms speed {rms_at_2s:.4} m/s at 2 s, {rms:.4} m/s at 4 s; rms drift {:.3} mm from 3 to 4.5 s",
        100.0 * worst_avg,
        100.0 * worst_max,
        samples.len(),
        1e3 * drift
    );
    assert_eq!(world.particles.len(), n);
    assert!(contained(&world, &scene));
    assert!(worst_avg <= 0.001, "average density error {worst_avg}");
    assert!(worst_max <= 0.01, "largest density error {worst_max}");
    assert_eq!(unconverged, 0);
    assert!((s - 1.0).abs() <= 0.02, "pressure over weight {s}");
    // At rest: the step's velocities below 1 % of the free-fall speed
    // √(g depth) ≈ 1.4 m/s (each step starts with g Δt = 0.05 m/s of fall
    // that its solves take out to their tolerance), and the particles
    // stay where they are: less than a quarter spacing from 3 to 4.5 s
    // (measured 3.6 mm: what is left of the settling's slosh, and jitter).
    assert!(rms < 0.02, "rms speed {rms} m/s");
    assert!(drift < 0.005, "rms drift {drift} m in 1.5 s");
}

/// The largest single-particle compression and the average compression
/// over the first second of the demo's slab dam break (`dam-break`, 1,200
/// particles), with the frame's steps, iterations and unconverged solves;
/// DFSPH's parameters `dfsph` where given, else the defaults.
fn dam_break_errors(
    kind: SolverKind,
    dfsph: Option<DfsphParams>,
) -> (f32, f32, u32, u32, u32, u32) {
    let mut scene = Scene::dam_break(0.25, 0.08, 0.02).with_solver(kind);
    scene.solver.dfsph = dfsph;
    let mut world = scene.build_world().unwrap();
    let n = world.particles.len();
    let (mut worst_avg, mut worst_max) = (0.0f32, 0.0f32);
    let (mut steps, mut iterations, mut divergence, mut unconverged) = (0, 0, 0, 0);
    for _ in 0..60 {
        let r = world.advance(1.0 / 60.0).unwrap();
        worst_avg = worst_avg.max(r.density_error_avg);
        worst_max = worst_max.max(r.density_error_max);
        steps += r.substeps;
        iterations += r.iterations;
        divergence += r.divergence_iterations;
        unconverged += r.unconverged;
        assert!(contained(&world, &scene));
    }
    assert_eq!(world.particles.len(), n);
    (
        worst_max,
        worst_avg,
        steps,
        iterations,
        divergence,
        unconverged,
    )
}

/// DFSPH against WCSPH on the dam break's first second: the densities each
/// step starts from (after the last step's motion), every step.
///
/// Measured (this test's output): DFSPH at most 0.867 % in a single
/// particle and 0.0561 % on average, in 594 steps; WCSPH 8.79 % and 0.127 %,
/// in 3,021 (without the scenes' default clearance: DFSPH 1.06 % and
/// 0.073 %, WCSPH 16.5 % and 0.45 %). Asserted: at most 1.25 % and 0.085 %, at most half WCSPH's
/// largest, in under a third of its steps. At the default density
/// tolerance, a mean compression of 0.05 %, single particles are left
/// above 1 %: the solve stops on the mean, the start's corner particles
/// and the front's impact on the far wall stay above it (1.94 % at 1 cm
/// spacing). A tolerance of 0.01 % holds them under 1 %:
/// [`dam_break_compression_at_a_tight_tolerance`].
#[test]
fn dam_break_compression() {
    let (max, avg, steps, iterations, divergence, unconverged) =
        dam_break_errors(SolverKind::Dfsph, None);
    let (wc_max, wc_avg, wc_steps, ..) = dam_break_errors(SolverKind::Wcsph, None);
    println!(
        "DFSPH: {steps} steps, {:.1} density + {:.1} divergence iterations per step, \
         {unconverged} unconverged; compression ≤ {:.3} % max, ≤ {:.4} % avg\n\
         WCSPH: {wc_steps} steps; compression ≤ {:.3} % max, ≤ {:.4} % avg",
        iterations as f64 / steps as f64,
        divergence as f64 / steps as f64,
        100.0 * max,
        100.0 * avg,
        100.0 * wc_max,
        100.0 * wc_avg
    );
    assert!(avg <= 0.00085, "average compression {avg}");
    assert!(max <= 0.0125, "largest compression {max}");
    assert!(
        max <= 0.5 * wc_max,
        "largest compression {max}, WCSPH {wc_max}"
    );
    assert_eq!(unconverged, 0);
    // Steps set by the flow: at most Ritter's 2√(gH) ≈ 4.4 m/s allows
    // λh/v ≈ 0.9 ms; WCSPH's speed of sound about 0.3 ms.
    assert!(steps * 3 < wc_steps, "{steps} steps, WCSPH {wc_steps}");
}

/// The 1 % for the single particle, met with the density solve's
/// tolerance at 0.01 % instead of the default 0.05 %, at the same steps.
///
/// Measured (this test's output): at most 0.573 % in a single particle
/// and 0.0193 % on average, in 589 steps, 15.8 density iterations per step
/// against 4.3 at the default; asserted at most 0.9 % and 0.045 %. (Before
/// the scenes' default clearance of half a spacing, 0.66 % and 0.035 %. At
/// 1 cm spacing, 10,000 particles, a throwaway copy of this test measured
/// 0.64 % in 1,148 steps, 21.8 iterations per step against 5.2, 1.8 times
/// the wall time.) The maximum is not monotonic in the tolerance (a sweep
/// found it higher at 0.03 % than at 0.05 %), so 0.01 % is the tolerance
/// to set where single particles matter, and the default stays the
/// issue's 0.05 % for speed.
#[test]
fn dam_break_compression_at_a_tight_tolerance() {
    let tight = DfsphParams {
        density_tolerance: 1e-4,
        ..DfsphParams::default()
    };
    let (max, avg, steps, iterations, _, unconverged) =
        dam_break_errors(SolverKind::Dfsph, Some(tight));
    let (.., default_steps, default_iterations, _, _) = dam_break_errors(SolverKind::Dfsph, None);
    println!(
        "DFSPH at a density tolerance of 0.01 %: {steps} steps, {:.1} density iterations \
         per step (default tolerance: {default_steps} steps, {:.1}), {unconverged} unconverged; \
         compression ≤ {:.3} % max, ≤ {:.4} % avg",
        iterations as f64 / steps as f64,
        default_iterations as f64 / default_steps as f64,
        100.0 * max,
        100.0 * avg,
    );
    assert!(max <= 0.009, "largest compression {max}");
    assert!(avg <= 0.00045, "average compression {avg}");
    assert_eq!(unconverged, 0);
    // The same steps, set by the flow: the tolerance buys iterations only.
    assert!(
        steps.abs_diff(default_steps) * 20 < default_steps,
        "{steps} steps against {default_steps}"
    );
}

/// Bitwise the same particles and reports for 1, 2 and 4 threads: the
/// solves' error means are summed in fixed chunks in a fixed order; with a
/// clearance, the solves' contacts are found and held in index order.
#[test]
fn identical_for_1_2_and_4_threads() {
    let mut scene = Scene::dam_break(0.16, 0.08, 0.02).with_solver(SolverKind::Dfsph);
    identical_for_thread_counts(&scene, 20, &[1, 2, 4]);
    scene.clearance = Some(0.01);
    identical_for_thread_counts(&scene, 20, &[1, 2, 4]);
    // And with the free surface's target.
    scene.solver.dfsph = Some(DfsphParams {
        surface_target: true,
        ..DfsphParams::default()
    });
    identical_for_thread_counts(&scene, 20, &[1, 2, 4]);
}

/// The same with surface tension (the `drops` scene under DFSPH: Akinci
/// et al.'s forces in lanes).
#[test]
fn identical_with_surface_tension_for_1_2_and_4_threads() {
    let drops = Scene::built_in("drops")
        .unwrap()
        .with_solver(SolverKind::Dfsph);
    assert!(drops.fluid.surface_tension > 0.0);
    identical_for_thread_counts(&drops, 10, &[1, 2, 4]);
}

/// The same for 1, 2, 3 and 7 threads at 10,000 particles
/// (`dam-break-fine`): each Jacobi and CG iteration runs in one parallel
/// region of 157 blocks, claimed a few at a time by however many threads
/// arrive, whose sums make the solves' error means and the CG's dot
/// products in block order. And with the free surface's target, whose
/// averaging is a pass of its own.
#[test]
fn identical_for_1_2_3_and_7_threads_at_10k_particles() {
    let mut scene = Scene::dam_break(0.25, 0.08, 0.01).with_solver(SolverKind::Dfsph);
    assert_eq!(scene.particles().unwrap().len(), 10_000);
    identical_for_thread_counts(&scene, 6, &[1, 2, 3, 7]);
    scene.solver.dfsph = Some(DfsphParams {
        surface_target: true,
        ..DfsphParams::default()
    });
    identical_for_thread_counts(&scene, 6, &[1, 2, 3, 7]);
}

/// The same above 32,768 particles (40,000), where the grid's build, the
/// particles' reordering and the other light passes split through rayon
/// by the pool's size (`sph_core::light`): two frames at 1, 2 and 3
/// threads.
#[test]
fn identical_for_1_2_and_3_threads_at_40k_particles() {
    let big = Scene::dam_break(0.25, 0.32, 0.01).with_solver(SolverKind::Dfsph);
    assert_eq!(big.particles().unwrap().len(), 40_000);
    identical_for_thread_counts(&big, 2, &[1, 2, 3]);
}

fn identical_for_thread_counts(scene: &Scene, frames: usize, threads: &[usize]) {
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let mut world = scene.build_world().unwrap();
                let mut reports = Vec::new();
                for _ in 0..frames {
                    let r = world.advance(1.0 / 60.0).unwrap();
                    reports.push((
                        r.substeps,
                        r.iterations,
                        r.divergence_iterations,
                        r.viscosity_iterations,
                        r.density_error_avg.to_bits(),
                        r.density_error_max.to_bits(),
                    ));
                }
                let p = &world.particles;
                let bits = |v: &[Vec3]| {
                    v.iter()
                        .flat_map(|x| x.to_array().map(f32::to_bits))
                        .collect::<Vec<_>>()
                };
                let pressures: Vec<u32> = p.pressures().iter().map(|x| x.to_bits()).collect();
                (
                    p.ids().to_vec(),
                    bits(p.positions()),
                    bits(p.velocities()),
                    pressures,
                    reports,
                )
            })
    };
    let first = run(threads[0]);
    for &t in &threads[1..] {
        assert!(first == run(t), "{t} threads differ from {}", threads[0]);
    }
}

/// Every DFSPH parameter that is zero, negative, NaN or absurd is an error
/// naming it, from the library, through a scene, and in a file.
#[test]
fn bad_parameters_are_errors_naming_the_field() {
    let d = DfsphParams::default();
    let cases = [
        ("dfsph.cfl", DfsphParams { cfl: 0.0, ..d }),
        ("dfsph.cfl", DfsphParams { cfl: f32::NAN, ..d }),
        ("dfsph.cfl", DfsphParams { cfl: 5.0, ..d }),
        ("dfsph.max_dt", DfsphParams { max_dt: -1.0, ..d }),
        (
            "dfsph.max_dt",
            DfsphParams {
                max_dt: f32::INFINITY,
                ..d
            },
        ),
        (
            "dfsph.density_tolerance",
            DfsphParams {
                density_tolerance: 0.0,
                ..d
            },
        ),
        (
            "dfsph.density_tolerance",
            DfsphParams {
                density_tolerance: f32::NAN,
                ..d
            },
        ),
        (
            "dfsph.density_tolerance",
            DfsphParams {
                density_tolerance: -1e-3,
                ..d
            },
        ),
        (
            "dfsph.divergence_tolerance",
            DfsphParams {
                divergence_tolerance: 0.0,
                ..d
            },
        ),
        (
            "dfsph.divergence_tolerance",
            DfsphParams {
                divergence_tolerance: f32::NAN,
                ..d
            },
        ),
        (
            "dfsph.max_iterations",
            DfsphParams {
                max_iterations: 0,
                ..d
            },
        ),
        (
            "dfsph.max_iterations",
            DfsphParams {
                max_iterations: u32::MAX,
                ..d
            },
        ),
        (
            "dfsph.sleep_speed",
            DfsphParams {
                sleep_speed: -0.01,
                ..d
            },
        ),
        (
            "dfsph.sleep_speed",
            DfsphParams {
                sleep_speed: f32::NAN,
                ..d
            },
        ),
    ];
    for (name, p) in cases {
        match p.validate() {
            Err(Error::InvalidParameter { name: got, .. }) => assert_eq!(got, name, "{p:?}"),
            other => panic!("{p:?}: {other:?}"),
        }
        let mut scene = Scene::dam_break(0.1, 0.04, 0.02).with_solver(SolverKind::Dfsph);
        scene.solver.dfsph = Some(p);
        let e = scene.build_world().unwrap_err().to_string();
        assert!(e.contains(&format!("solver.{name}")), "{e}");
    }
    // A sleeping threshold at g × max_dt (0.049 m/s) would hold fluid at
    // rest in the air: refused when the world is built, by name.
    let mut scene = Scene::dam_break(0.1, 0.04, 0.02).with_solver(SolverKind::Dfsph);
    scene.solver.dfsph = Some(DfsphParams {
        sleep_speed: 0.05,
        ..d
    });
    let e = scene.build_world().unwrap_err().to_string();
    assert!(e.contains("solver.dfsph.sleep_speed"), "{e}");
    let mut scene = Scene::dam_break(0.1, 0.04, 0.02).with_solver(SolverKind::Dfsph);
    scene.solver.dfsph = Some(d);
    let text = scene.to_toml();
    assert!(text.contains("max_iterations = 100"), "{text}");
    let e = Scene::from_toml(&text.replace("max_iterations = 100", "max_iterations = 0"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("solver.dfsph.max_iterations"), "{e}");
    assert_eq!(Scene::from_toml(&text).unwrap().dfsph_params(), d);
}

/// Particle sleeping skips steps in which gravity gives less than the
/// threshold: a block at rest in the air with a threshold of 0.99 g ×
/// max_dt, stepped in frames of 1/300 s (steps of 3.3 ms, g Δt two thirds
/// of the threshold), falls exactly as without sleeping. A threshold
/// above g × max_dt is refused when the world is built, by name.
#[test]
fn sleeping_skips_steps_too_short_to_start_a_fall() {
    let spacing = 0.02;
    let params = FluidParams::water(2.0 * spacing);
    let mass = params.particle_mass(spacing).unwrap();
    let g_max_dt = 9.81 * DfsphParams::default().max_dt;
    let world = |sleep_speed: f32| {
        let particles = common::lattice(6, spacing, Vec3::ZERO, mass);
        let dfsph = DfsphParams {
            sleep_speed,
            ..DfsphParams::default()
        };
        common::unbounded(particles, params, Solver::Dfsph(dfsph))
    };
    let fall = |sleep_speed| {
        let mut world = world(sleep_speed).unwrap();
        for _ in 0..30 {
            world.advance(1.0 / 300.0).unwrap();
        }
        world.particles.positions().to_vec()
    };
    let awake = fall(0.0);
    assert_eq!(awake, fall(0.99 * g_max_dt));
    let mean_y = awake.iter().map(|x| x.y).sum::<f32>() / awake.len() as f32;
    assert!(
        mean_y < 0.05 - 0.04,
        "the block fell to a mean height of {mean_y} m"
    );
    match world(1.01 * g_max_dt) {
        Err(Error::InvalidParameter { name, .. }) => assert_eq!(name, "dfsph.sleep_speed"),
        other => panic!("expected the threshold refused, got {:?}", other.err()),
    }
}

/// Particles started a third of the spacing apart are 27 times denser than
/// rest: the density solve cannot bring them back within its two
/// iterations, so the run stops with `Error::Unstable` and a hint rather
/// than flying apart.
#[test]
fn a_failed_solve_stops_the_run() {
    let mut scene = Scene::dam_break(0.1, 0.04, 0.02).with_solver(SolverKind::Dfsph);
    scene.solver.dfsph = Some(DfsphParams {
        max_iterations: 2,
        ..DfsphParams::default()
    });
    let mut particles = scene.particles().unwrap();
    let centre = Vec3::new(0.05, 0.05, 0.02);
    let f = particles.fields_mut();
    for x in f.positions.iter_mut() {
        *x = centre + (*x - centre) / 3.0;
    }
    let mut world = scene.world_with(particles).unwrap();
    match world.advance(1.0 / 60.0) {
        Err(Error::Unstable { what, hint, .. }) => {
            assert!(what.contains("solve diverged"), "{what}");
            assert!(hint.contains("solver.dfsph"), "{hint}");
        }
        other => panic!("{other:?}"),
    }
}

/// Surface tension under DFSPH (Akinci et al.'s forces for water's σ, the
/// scale and cohesion weight measured on PBF's and DFSPH's drops): a weightless drop of 4,032 particles at
/// 3.5 mm (R = 34.6 mm) stretched along x oscillates in Rayleigh's l = 2
/// mode at his period 2π/ω, ω² = 8σ/(ρR³), within 10 %, as the median of
/// three stretches (10, 12 and 15 %; one drop's period moves by several
/// per cent with rounding-level changes). Measured over 4 s (sorted):
/// 0.887, 0.927 and 0.937 of Rayleigh's.
#[test]
fn a_drop_oscillates_at_rayleighs_period() {
    let dfsph = sph_core::Solver::Dfsph(DfsphParams::default());
    let mut ratios: Vec<f64> = [1.10f32, 1.12, 1.15]
        .map(|stretch| common::drop_period(dfsph, 0.0035, stretch, 4.0))
        .to_vec();
    ratios.sort_by(f64::total_cmp);
    println!("period / Rayleigh's: {ratios:.3?}");
    assert!((ratios[1] - 1.0).abs() <= 0.1, "{ratios:?}");
}

/// Laplace's law under DFSPH with Akinci et al.'s forces: a weightless
/// water drop of 4,032 particles at 5 mm (R = 49.4 mm, 9.9 spacings), at
/// rest on the lattice from the start, holds a mechanical pressure within
/// R/2 of its centre of about four fifths of 2σ/R = 2.95 Pa, read as every
/// pair force's virial over every step of the last of 8 s, weighted by the
/// step (`common::dfsph_drop_laplace`).
///
/// Measured: 0.805. Issue 42's 10 % is missed. (Read after each 1/60 s
/// frame only, as this test did before, the same drop read 0.909: DFSPH's
/// pressure pulses with the unequal steps a frame is split into, and the
/// frame's last step is short. PBF's equal substeps read the same either
/// way: 0.947 and 0.941 on `rayleigh_drop`'s 16-across drop.) Held: within
/// [0.7, 1.1], which Akinci's forces lost, halved or doubled would leave.
///
/// Other drops (`cargo run --release -p sph-core --example rayleigh_drop --
/// dfsph 4 --shape ellipsoid --eps 0 --across N`, the same per-step
/// reading): 0.634 and 0.684 at R = 14 and 20 spacings of 5 mm (N = 23,
/// 32), against PBF's 0.933 and 0.895 (`solver::surface_tension`'s module
/// docs).
#[test]
fn a_drop_at_rest_holds_most_of_laplaces_pressure() {
    let ratio = common::dfsph_drop_laplace(0.005, 8.0);
    println!("inner pressure / Laplace's 2σ/R: {ratio:.3}");
    assert!((0.7..=1.1).contains(&ratio), "{ratio:.3}");
}

/// Rayleigh's l = 4 mode under DFSPH, at small amplitude, as PBF's test
/// (`common::drop_l4_period`, a damped-sinusoid fit, the median of `eps` =
/// 0.08, 0.10 and 0.12, damped and undamped). Measured, damped / undamped
/// medians: 1.217 / 1.193 of Rayleigh's period at 5 mm (R = 5 h), 1.090 /
/// 1.051 at 3.5 mm (7 h); with the paper's equal weights of cohesion and
/// curvature (`surface_tension::COHESION_WEIGHT` = 1, scale 13) they were
/// 1.453 / 1.359 and 1.126 / 0.993. Held: at 3.5 mm the undamped period
/// within issue 42's 10 % and the damped one within 20 %; at 5 mm the
/// damped one within 30 %, and at least 0.1 longer than at 3.5 mm.
///
/// A second resolution, 2.5 mm (R = 20 spacings, 32,752 particles), one
/// amplitude (0.1): measured 1.009 damped, 0.950 undamped; held as at
/// 3.5 mm.
#[test]
fn a_drop_rings_near_rayleighs_l4_period_when_resolved() {
    let dfsph = sph_core::Solver::Dfsph(DfsphParams::default());
    let median = |spacing, across| common::drop_l4_medians(dfsph, spacing, across);
    let (coarse, fine) = (median(0.005, 16), median(0.0035, 23));
    assert!((0.8..=1.2).contains(&fine.0), "3.5 mm: {fine:?}");
    assert!((0.9..=1.1).contains(&fine.1), "3.5 mm: {fine:?}");
    assert!((0.7..=1.3).contains(&coarse.0), "5 mm: {coarse:?}");
    assert!(coarse.0 - fine.0 >= 0.1, "5 mm {coarse:?}, 3.5 mm {fine:?}");
    let finer = common::drop_l4_period(dfsph, 0.0025, 32, 0.1, 3.0);
    println!("0.0025 m: period / Rayleigh's, damped and undamped {finer:.3?}");
    assert!((0.8..=1.2).contains(&finer.0), "2.5 mm: {finer:?}");
    assert!((0.9..=1.1).contains(&finer.1), "2.5 mm: {finer:?}");
}
