//! Position-based fluids against physics: a hydrostatic tank, a column at
//! rest and in free fall over 10,000 substeps, a block that particle
//! sleeping does not hold in the air, momentum of a free cluster,
//! the dam-break front against Ritter, determinism across threads, and bad
//! input.

mod common;

use glam::Vec3;
use sph_core::{
    Boundary, Error, FluidParams, Particles, PbfParams, PbfSolve, PbfViscosity, Scene, Solver,
    SolverKind, World,
};

/// Deterministic pseudo-random numbers in [-1, 1).
fn noise(seed: &mut u64) -> f32 {
    *seed = seed
        .wrapping_mul(6_364_136_223_846_793_005)
        .wrapping_add(1_442_695_040_888_963_407);
    ((*seed >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
}

/// `particles` in a domain far larger than they reach, run by PBF, with
/// the fluid's surface tension off.
fn unbounded(particles: Particles, params: FluidParams, pbf: PbfParams) -> World {
    common::unbounded(particles, params, Solver::Pbf(pbf)).unwrap()
}

/// Whether every particle is inside the domain and out of the obstacles.
fn contained(world: &World, boundary: &Boundary) -> bool {
    world
        .particles
        .positions()
        .iter()
        .all(|&x| boundary.admits(x))
}

fn rms_speed(p: &Particles) -> f32 {
    let sum: f64 = p
        .velocities()
        .iter()
        .map(|v| f64::from(v.length_squared()))
        .sum();
    (sum / p.len() as f64).sqrt() as f32
}

/// A tank `w` wide, 0.08 m deep, filled to `depth`, run by PBF.
fn tank(w: f32, depth: f32, pbf: PbfParams) -> Scene {
    let spacing = 0.02;
    let mut scene = Scene::dam_break(w, 0.08, spacing).with_solver(SolverKind::Pbf);
    scene.domain.max = [w, depth + 0.1, 0.08];
    scene.blocks[0].max = [w, depth, 0.08];
    scene.solver.pbf = Some(pbf);
    scene
}

/// A tank 10 particles deep settles to an average density error of at most
/// 1 % with the default 3 substeps × 3 iterations per 60 Hz frame: nothing
/// escapes, it comes to rest up to PBF's jitter, and the pressure its solve
/// applies grows with depth at about ρ0 g.
#[test]
fn hydrostatic_tank() {
    let scene = tank(0.3, 0.2, PbfParams::default());
    let boundary = scene.boundary();
    let mut world = scene.build_world().unwrap();
    let n = world.particles.len();
    let mut last = None;
    let (w, depth, h) = (0.3, 0.2, scene.fluid.h);
    let (mut ys, mut ps) = (Vec::new(), Vec::new());
    for frame in 0..180 {
        let r = world.advance(1.0 / 60.0).unwrap();
        assert_eq!(
            (r.solver, r.substeps, r.iterations),
            (SolverKind::Pbf, 3, 9)
        );
        if frame >= 120 {
            let p = &world.particles;
            for (x, &pressure) in p.positions().iter().zip(p.pressures()) {
                if x.x > 2.0 * h && x.x < w - 2.0 * h && x.y > 2.0 * h && x.y < depth - h {
                    ys.push(x.y);
                    ps.push(pressure);
                }
            }
            last = Some(r);
            assert!(
                r.density_error_avg <= 0.01,
                "frame {frame}: average density error {}",
                r.density_error_avg
            );
        }
    }
    let r = last.unwrap();
    let rms = rms_speed(&world.particles);
    let slope = common::pressure_slope(&ys, &ps);
    let expected = -f64::from(scene.fluid.rest_density * 9.81);
    println!(
        "{n} particles after 3 s: density error {:.3} % avg, {:.2} % max; rms speed {rms:.4} m/s; \
         pressure slope {slope:.0} Pa/m over {} samples (ρ0 g = {:.0}, {:+.2} %)",
        100.0 * r.density_error_avg,
        100.0 * r.density_error_max,
        ys.len(),
        -expected,
        100.0 * (slope / expected - 1.0),
    );
    assert_eq!(world.particles.len(), n);
    assert!(contained(&world, &boundary));
    // At rest, up to PBF's jitter (gravity's pull each substep, not quite
    // undone by 3 iterations; measured 0.08 m/s): slower than a 0.5 mm
    // fall (0.1 m/s), 5 % of the 2 m/s of a fall through the tank.
    assert!(rms < 0.1, "rms speed {rms} m/s");
    assert_eq!(r.clamped, 0);
    // The pressure the solve applied (p = −ω ρ0 Σλ/Δt²) against depth,
    // more than 2h from the end walls and the floor and h below the
    // surface, at the end of each frame of the third second: measured
    // +21.7 % from ρ0 g (+24.9 % while the walls' layers were V^⅓ apart; an
    // earlier version of the solver read +0.29 %). The one-sided
    // constraint answers the rest jitter's compressions and not its
    // rarefactions, which biases the mean pressure upwards by an amount
    // that grows with depth. That earlier version measured +7.3 % at 1.05
    // g, +31 % at g/2, +17 % at 10 iterations and +9 % at 6 substeps (a
    // throwaway loop over this test). So the band is [−2 %, +40 %]: it
    // holds against a pressure of the wrong sign, scale (Δt for Δt², a
    // substep's for the frame's) or none, not against the jitter.
    assert!(
        (0.98..=1.4).contains(&(slope / expected)),
        "pressure slope {slope} Pa/m against {expected}"
    );
}

/// 10,000 substeps of a column at rest (5,000 frames) stay finite,
/// contained, at rest and within 2 % average density error.
#[test]
fn column_at_rest_for_ten_thousand_substeps() {
    let scene = tank(0.12, 0.3, PbfParams::default());
    let boundary = scene.boundary();
    let mut world = scene.build_world().unwrap();
    let n = world.particles.len();
    let (mut substeps, mut worst) = (0, 0.0f32);
    while substeps < 10_000 {
        let r = world.advance(1.0 / 60.0).unwrap();
        substeps += r.substeps;
        if substeps > 1_000 {
            worst = worst.max(r.density_error_avg);
        }
    }
    let rms = rms_speed(&world.particles);
    println!(
        "{n} particles, {substeps} substeps: worst average density error {worst:.4}, rms speed {rms:.4}"
    );
    assert!(contained(&world, &boundary));
    // Measured: 1.05 % and 0.105 m/s (15 particles deep, the jitter of
    // the tank above grows with depth).
    assert!(worst < 0.02, "average density error up to {worst}");
    assert!(rms < 0.15, "rms speed {rms} m/s");
}

/// A block falling freely for 10,000 substeps (1 s at 0.1 ms) keeps its
/// shape: every particle gains g t, none moves relative to the others.
#[test]
fn free_fall_for_ten_thousand_substeps() {
    let spacing = 0.02;
    let params = FluidParams::water(2.0 * spacing);
    let mass = params.particle_mass(spacing).unwrap();
    let particles = common::lattice(6, spacing, Vec3::ZERO, mass);
    let start = particles.positions().to_vec();
    let pbf = PbfParams {
        substeps: 1_000,
        max_dt: 1e-4,
        ..PbfParams::default()
    };
    let mut world = unbounded(particles, params, pbf);
    let mut substeps = 0;
    for _ in 0..10 {
        substeps += world.advance(0.1).unwrap().substeps;
    }
    assert_eq!(substeps, 10_000);
    let t = world.time() as f32;
    let g = params.gravity;
    for (i, (x, v)) in world
        .particles
        .positions()
        .iter()
        .zip(world.particles.velocities())
        .enumerate()
    {
        let id = world.particles.ids()[i] as usize;
        let expected = start[id] + 0.5 * g * t * t;
        // Semi-implicit Euler's fall lags ½ g t Δt behind the exact one.
        assert!(
            (*x - expected).length() < 1e-3,
            "particle {id}: {x} vs {expected}"
        );
        assert!((*v - g * t).length() < 1e-3, "particle {id}: v = {v}");
    }
}

/// Particle sleeping holds a particle only where its substep would move it
/// slower than the threshold: a block at rest in the air, at a threshold
/// just below g Δt (the most a frame accepts), falls exactly as without
/// sleeping, and a threshold above g Δt is refused before the first
/// substep, by name, leaving the particles where they were.
#[test]
fn sleeping_below_g_dt_lets_a_block_fall() {
    let spacing = 0.02;
    let params = FluidParams::water(2.0 * spacing);
    let mass = params.particle_mass(spacing).unwrap();
    let g_dt = 9.81 * PbfParams::default().max_dt;
    let run = |sleep_speed: f32| {
        let particles = common::lattice(6, spacing, Vec3::ZERO, mass);
        let pbf = PbfParams {
            sleep_speed,
            ..PbfParams::default()
        };
        let mut world = unbounded(particles, params, pbf);
        for _ in 0..15 {
            world.advance(1.0 / 60.0)?;
        }
        Ok::<_, Error>(world.particles.positions().to_vec())
    };
    let awake = run(0.0).unwrap();
    let asleep = run(0.99 * g_dt).unwrap();
    assert_eq!(awake, asleep);
    // 15 frames, t = 0.25 s, of semi-implicit Euler's fall: ½ g t (t + Δt).
    let (t, dt) = (0.25, PbfParams::default().max_dt);
    let drop = 0.05 - awake.iter().map(|x| x.y).sum::<f32>() / awake.len() as f32;
    let expected = 0.5 * 9.81 * t * (t + dt);
    assert!(
        (drop - expected).abs() < 1e-3,
        "fell {drop} m, not {expected}"
    );
    let particles = common::lattice(6, spacing, Vec3::ZERO, mass);
    let start = particles.positions().to_vec();
    let pbf = PbfParams {
        sleep_speed: 1.01 * g_dt,
        ..PbfParams::default()
    };
    let mut world = unbounded(particles, params, pbf);
    match world.advance(1.0 / 60.0) {
        Err(Error::InvalidParameter { name, .. }) => assert_eq!(name, "pbf.sleep_speed"),
        other => panic!("expected the threshold refused, got {other:?}"),
    }
    assert_eq!(world.particles.positions(), &start[..]);
}

/// No gravity, no walls within reach, no vorticity confinement (a body
/// force): the pairwise-antisymmetric corrections and XSPH keep the total
/// momentum of a cluster of unequal masses to round-off.
#[test]
fn free_cluster_keeps_its_momentum() {
    let spacing = 0.02;
    let mut params = FluidParams::water(2.0 * spacing);
    params.gravity = Vec3::ZERO;
    let mass = params.particle_mass(spacing).unwrap();
    let mut particles = Particles::new();
    let mut seed = 11;
    for k in 0..8 {
        for j in 0..8 {
            for i in 0..8 {
                // Squeezed to 0.85 spacing: compressed, so the solve acts.
                let x = Vec3::new(i as f32, j as f32, k as f32) * 0.85 * spacing
                    + Vec3::new(noise(&mut seed), noise(&mut seed), noise(&mut seed))
                        * 0.1
                        * spacing;
                let v = Vec3::new(noise(&mut seed), noise(&mut seed), noise(&mut seed)) * 0.2;
                particles.push(x, v, mass * (1.0 + 0.05 * noise(&mut seed)));
            }
        }
    }
    let momentum = |p: &Particles| {
        p.masses()
            .iter()
            .zip(p.velocities())
            .fold([0.0f64; 3], |mut m, (&mass, v)| {
                for a in 0..3 {
                    m[a] += f64::from(mass) * f64::from(v[a]);
                }
                m
            })
    };
    let before = momentum(&particles);
    let energy = |p: &Particles| -> f64 {
        (p.masses().iter().zip(p.velocities()))
            .map(|(&m, v)| 0.5 * f64::from(m) * f64::from(v.length_squared()))
            .sum()
    };
    // Plain and over-relaxed Jacobi: ω scales each antisymmetric pair term;
    // and Gauss–Seidel, whose constraint i pushes i and each neighbour by
    // opposite momenta.
    // Warm-started, its carried pressures make a Jacobi-form move first.
    for (over_relaxation, solve, warm_start) in [
        (1.0, PbfSolve::Jacobi, 0.0),
        (1.25, PbfSolve::Jacobi, 0.0),
        (1.0, PbfSolve::GaussSeidel, 0.0),
        (1.0, PbfSolve::GaussSeidel, 0.5),
    ] {
        let pbf = PbfParams {
            vorticity: 0.0,
            over_relaxation,
            solve,
            warm_start,
            ..PbfParams::default()
        };
        let mut world = unbounded(particles.clone(), params, pbf);
        let mut first = None;
        for _ in 0..30 {
            let r = world.advance(1.0 / 60.0).unwrap();
            assert_eq!(r.clamped, 0);
            first.get_or_insert(r.density_error_max);
        }
        let after = momentum(&world.particles);
        // The solve did act: the squeezed cluster (63 % over rest density)
        // pushed itself apart, turning compression into motion that XSPH
        // alone, which only evens velocities out, could not make (measured
        // ×133 at ω = 1, ×201 at 1.25).
        let gained = energy(&world.particles) / energy(&particles);
        // The scale: total mass × the mean speed.
        let scale = world.particles.total_mass() * 0.1;
        for a in 0..3 {
            assert!(
                (after[a] - before[a]).abs() < 1e-6 * scale,
                "{solve:?}, ω = {over_relaxation}, axis {a}: {} → {}",
                before[a],
                after[a]
            );
        }
        println!(
            "{solve:?}, ω = {over_relaxation}: momentum {before:?} → {after:?}; largest density \
             error {:.4} after the first frame; kinetic energy ×{gained:.2}",
            first.unwrap()
        );
        assert!(
            gained > 50.0,
            "{solve:?}, ω = {over_relaxation}: kinetic energy ×{gained}"
        );
    }
}

/// Over-relaxation lowers the density error at the same iterations: a
/// tank 25 particles deep at 3 × 3, settled for 2 s, averaged over the
/// third (measured: 1.80 % at ω = 1, 1.31 % at 1.25, with rms speeds at
/// rest of 0.16 and 0.22 m/s; `pbf_convergence`).
#[test]
fn over_relaxation_lowers_the_density_error() {
    let settle = |over_relaxation| {
        settled_tank(PbfParams {
            over_relaxation,
            ..PbfParams::default()
        })
    };
    let (plain, plain_rms) = settle(1.0);
    let (over, over_rms) = settle(1.25);
    println!(
        "density error {:.3} % at ω = 1, {:.3} % at 1.25; rms speed {plain_rms:.3}, {over_rms:.3} m/s",
        100.0 * plain,
        100.0 * over
    );
    assert!(over < 0.8 * plain, "{over} against {plain}");
    assert!(over_rms < 0.3, "rms speed {over_rms} m/s");
}

/// A tank 0.3 m wide and 25 particles deep under `pbf`, settled for 2 s:
/// its average density error over the third second, and its rms speed
/// then (m/s).
fn settled_tank(pbf: PbfParams) -> (f32, f32) {
    let scene = tank(0.3, 0.5, pbf);
    let boundary = scene.boundary();
    let mut world = scene.build_world().unwrap();
    let mut error = 0.0f32;
    for frame in 0..180 {
        let r = world.advance(1.0 / 60.0).unwrap();
        if frame >= 120 {
            error += r.density_error_avg / 60.0;
        }
    }
    assert!(contained(&world, &boundary));
    (error, rms_speed(&world.particles))
}

/// Gauss–Seidel's warm start (`PbfParams::warm_start`) carries the deep
/// tank's pressure over from the last substep, which the cold sweeps
/// rebuild by compressing it: at half the last pressure the average
/// density error over the third second falls by over 40 %, and the tank
/// moves at under a third of the speed (measured 1.89 % against 0.94 %,
/// 72.7 against 15.3 mm/s).
#[test]
fn a_warm_start_lowers_gauss_seidels_density_error() {
    let settle = |warm_start| {
        settled_tank(PbfParams {
            solve: PbfSolve::GaussSeidel,
            warm_start,
            ..PbfParams::default()
        })
    };
    let (cold, cold_rms) = settle(0.0);
    let (warm, warm_rms) = settle(0.5);
    println!(
        "density error {:.3} % cold, {:.3} % warm; rms speed {cold_rms:.4}, {warm_rms:.4} m/s",
        100.0 * cold,
        100.0 * warm
    );
    assert!(warm < 0.6 * cold, "{warm} against {cold}");
    assert!(
        warm_rms < 0.33 * cold_rms,
        "rms speed {warm_rms} against {cold_rms} m/s"
    );
}

/// Bitwise the same particles and reports for 1, 2 and 4 threads, with
/// XSPH, with the implicit viscosity (whose conjugate gradients sum in
/// fixed chunks), with particle sleeping and with the Gauss–Seidel solve,
/// over half a second of a small dam break.
#[test]
fn identical_for_1_2_and_4_threads() {
    let [xsph, implicit] = with_both_viscosities(Scene::dam_break(0.16, 0.08, 0.02));
    // And with particle sleeping, which holds particles one by one.
    let mut sleeping = xsph.clone();
    sleeping.solver.pbf = Some(PbfParams {
        sleep_speed: 0.02,
        ..xsph.pbf_params()
    });
    // Sleeping holds some particles here: the run differs from XSPH's.
    let positions = |scene: &Scene| {
        let mut world = scene.build_world().unwrap();
        for _ in 0..30 {
            world.advance(1.0 / 60.0).unwrap();
        }
        world.particles.positions().to_vec()
    };
    assert_ne!(positions(&xsph), positions(&sleeping));
    // And Gauss–Seidel, whose columns of one colour relax side by side.
    let mut gauss_seidel = xsph.clone();
    gauss_seidel.solver.pbf = Some(PbfParams {
        solve: PbfSolve::GaussSeidel,
        ..xsph.pbf_params()
    });
    // Warm-started, with each λ clamped as a sum, and the surface target.
    let mut warm = xsph.clone();
    warm.solver.pbf = Some(PbfParams {
        solve: PbfSolve::GaussSeidel,
        warm_start: 0.5,
        surface_target: true,
        ..xsph.pbf_params()
    });
    for scene in [xsph, implicit, sleeping, gauss_seidel, warm] {
        identical_for_thread_counts(&scene, 30, &[1, 2, 4]);
    }
}

/// The same with surface tension (the `drops` scene: Akinci et al.'s
/// forces in lanes, 4,394 particles).
#[test]
fn identical_with_surface_tension_for_1_2_and_4_threads() {
    let drops = Scene::built_in("drops").unwrap();
    assert!(drops.fluid.surface_tension > 0.0);
    identical_for_thread_counts(&drops, 10, &[1, 2, 4]);
}

/// The same for 1, 2, 3 and 7 threads at 10,000 particles
/// (`dam-break-fine`), past the 4,096 particles of a chunk of the report's
/// fixed-order density errors (three chunks, which a thread count that
/// split them otherwise would sum in another order), and with the
/// density solve, the vorticity and XSPH station and the CG iterations
/// each in one parallel region: 157 blocks, claimed a few at a time by
/// however many threads arrive, their sums added in block order. And
/// under Gauss–Seidel (warm-started, with the free surface's target),
/// whose colours' columns are claimed the same way, and whose warm start
/// and target are passes of their own.
#[test]
fn identical_for_1_2_3_and_7_threads_at_10k_particles() {
    let fine = Scene::dam_break(0.25, 0.08, 0.01);
    assert_eq!(fine.particles().unwrap().len(), 10_000);
    let [xsph, implicit] = with_both_viscosities(fine);
    let mut gauss_seidel = xsph.clone();
    gauss_seidel.solver.pbf = Some(PbfParams {
        solve: PbfSolve::GaussSeidel,
        warm_start: 0.5,
        surface_target: true,
        ..xsph.pbf_params()
    });
    for scene in [xsph, implicit, gauss_seidel] {
        identical_for_thread_counts(&scene, 6, &[1, 2, 3, 7]);
    }
}

/// The same above 32,768 particles (40,000), where the grid's build, the
/// particles' reordering and the other light passes split through rayon
/// by the pool's size (`sph_core::light`) instead of running on one
/// thread: two frames at 1, 2 and 3 threads.
#[test]
fn identical_for_1_2_and_3_threads_at_40k_particles() {
    let big = Scene::dam_break(0.25, 0.32, 0.01).with_solver(SolverKind::Pbf);
    assert_eq!(big.particles().unwrap().len(), 40_000);
    identical_for_thread_counts(&big, 2, &[1, 2, 3]);
}

/// A scene smaller than the caller's pool gains from steps on
/// `useful_threads` of them (every one with `use_every_thread`), and gives
/// the same results as on any count.
#[test]
fn a_small_scene_steps_on_the_threads_it_gains_from() {
    use sph_core::processor::{Context, Processor};
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// Records the threads of the pool the step's processors run in.
    struct PoolSize(Arc<AtomicUsize>);
    impl Processor for PoolSize {
        fn name(&self) -> &str {
            "pool size"
        }
        fn process(&mut self, _: &mut Particles, _: &mut Context) -> sph_core::error::Result<()> {
            self.0
                .store(rayon::current_num_threads(), Ordering::Relaxed);
            Ok(())
        }
    }

    let scene = Scene::dam_break(0.16, 0.08, 0.02).with_solver(SolverKind::Pbf);
    let want = sph_core::useful_threads(scene.particles().unwrap().len());
    assert_eq!(want, 8);
    let run = |threads, every| {
        let seen = Arc::new(AtomicUsize::new(0));
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let positions = pool.install(|| {
            let mut world = scene.build_world().unwrap();
            world.use_every_thread(every);
            world.program_mut().push(PoolSize(seen.clone()));
            for _ in 0..3 {
                world.advance(1.0 / 60.0).unwrap();
            }
            world.step().unwrap();
            world.particles.positions().to_vec()
        });
        (seen.load(Ordering::Relaxed), positions)
    };
    let (narrow, narrowed) = run(12, false);
    let (every, wide) = run(12, true);
    let (all, whole) = run(3, false);
    assert_eq!((narrow, every, all), (want, 12, 3));
    assert_eq!(narrowed, whole);
    assert_eq!(wide, whole);
}

/// `scene` under PBF with XSPH, and with the implicit viscosity.
fn with_both_viscosities(scene: Scene) -> [Scene; 2] {
    let xsph = scene.with_solver(SolverKind::Pbf);
    let mut implicit = xsph.clone();
    implicit.solver.pbf = Some(PbfParams {
        viscosity: PbfViscosity::Implicit,
        ..xsph.pbf_params()
    });
    [xsph, implicit]
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
                        r.density_error_avg.to_bits(),
                        r.density_error_max.to_bits(),
                        r.viscosity_iterations,
                    ));
                }
                let p = &world.particles;
                let bits = |v: &[Vec3]| {
                    v.iter()
                        .flat_map(|x| x.to_array().map(f32::to_bits))
                        .collect::<Vec<_>>()
                };
                let scalars = (p.densities().iter().chain(p.pressures()))
                    .map(|x| x.to_bits())
                    .collect::<Vec<_>>();
                (
                    p.ids().to_vec(),
                    bits(p.positions()),
                    bits(p.velocities()),
                    scalars,
                    reports,
                )
            })
    };
    let first = run(threads[0]);
    for &t in &threads[1..] {
        assert!(
            first == run(t),
            "{:?}: {t} threads differ from {}",
            scene.pbf_params().viscosity,
            threads[0]
        );
    }
}

/// The dam-break surge never runs ahead of Ritter's dry-bed front 2√(gH),
/// everything stays in the tank, and the front does run out: measured at
/// 0.43 of Ritter's speed (WCSPH: 0.46; `tests/solver.rs`), so PBF's front is
/// the slower, damped by XSPH and by iterations that leave the flow a little
/// compressed.
#[test]
fn dam_break_front_within_ritter() {
    let (a, spacing) = (0.2f32, 0.02f32);
    let scene = Scene::dam_break(a, 3.0 * spacing, spacing).with_solver(SolverKind::Pbf);
    let boundary = scene.boundary();
    let mut world = scene.build_world().unwrap();
    let front = |w: &World| {
        (w.particles.positions().iter())
            .map(|x| x.x)
            .fold(f32::MIN, f32::max)
    };
    let front0 = front(&world);
    let ritter = 2.0 * (9.81f32 * 2.0 * a).sqrt();
    let h = scene.fluid.h;
    let mut fastest = 0.0f32;
    for frame in 0..120 {
        world.advance(1.0 / 60.0).unwrap();
        let (t, f) = (world.time() as f32, front(&world));
        if f < scene.domain.max[0] - h {
            fastest = fastest.max((f - front0 - h) / t);
            assert!(
                f - front0 <= ritter * t + h,
                "frame {frame}: front moved {} m in {t} s, Ritter allows {}",
                f - front0,
                ritter * t
            );
        }
        assert!(contained(&world, &boundary));
    }
    println!("front speed (minus h) at most {fastest:.3} m/s vs Ritter {ritter:.3} m/s");
    // Measured 0.429 of Ritter's speed; asserted within 0.04 of that.
    assert!(
        (fastest / ritter - 0.429).abs() <= 0.04,
        "front at most {fastest} m/s, Ritter {ritter} m/s"
    );
}

/// Every PBF parameter that is zero, negative, NaN or absurd is an error
/// naming it, from the library and from a scene file.
#[test]
fn bad_parameters_are_errors_naming_the_field() {
    let d = PbfParams::default();
    let scorr = PbfParams { scorr_k: 0.01, ..d };
    let implicit = PbfParams {
        viscosity: PbfViscosity::Implicit,
        ..d
    };
    let cases: Vec<(&str, PbfParams)> = vec![
        ("pbf.substeps", PbfParams { substeps: 0, ..d }),
        (
            "pbf.substeps",
            PbfParams {
                substeps: 1_000_000,
                ..d
            },
        ),
        ("pbf.iterations", PbfParams { iterations: 0, ..d }),
        (
            "pbf.iterations",
            PbfParams {
                iterations: u32::MAX,
                ..d
            },
        ),
        ("pbf.max_dt", PbfParams { max_dt: 0.0, ..d }),
        (
            "pbf.max_dt",
            PbfParams {
                max_dt: f32::NAN,
                ..d
            },
        ),
        ("pbf.max_dt", PbfParams { max_dt: 1e9, ..d }),
        (
            "pbf.relaxation",
            PbfParams {
                relaxation: 0.0,
                ..d
            },
        ),
        (
            "pbf.relaxation",
            PbfParams {
                relaxation: -1.0,
                ..d
            },
        ),
        (
            "pbf.relaxation",
            PbfParams {
                relaxation: f32::INFINITY,
                ..d
            },
        ),
        ("pbf.scorr_k", PbfParams { scorr_k: -0.1, ..d }),
        // Fields the other settings leave unread, given away from their
        // defaults: s_corr's n and Δq while it is off, XSPH's blend under
        // the implicit viscosity and the implicit solve's settings under
        // XSPH.
        ("pbf.scorr_n", PbfParams { scorr_n: 2, ..d }),
        ("pbf.scorr_dq", PbfParams { scorr_dq: 0.3, ..d }),
        (
            "pbf.xsph",
            PbfParams {
                viscosity: PbfViscosity::Implicit,
                xsph: 0.1,
                ..d
            },
        ),
        (
            "pbf.viscosity_tolerance",
            PbfParams {
                viscosity_tolerance: 1e-4,
                ..d
            },
        ),
        (
            "pbf.viscosity_max_iterations",
            PbfParams {
                viscosity_max_iterations: 20,
                ..d
            },
        ),
        (
            "pbf.scorr_k",
            PbfParams {
                scorr_k: f32::NAN,
                ..d
            },
        ),
        // s_corr's ranges, with s_corr on (off, n and Δq away from their
        // defaults are refused as unread, below).
        (
            "pbf.scorr_n",
            PbfParams {
                scorr_n: 0,
                ..scorr
            },
        ),
        (
            "pbf.scorr_dq",
            PbfParams {
                scorr_dq: 0.0,
                ..scorr
            },
        ),
        (
            "pbf.scorr_dq",
            PbfParams {
                scorr_dq: 1.5,
                ..scorr
            },
        ),
        // Each fine alone; together s_corr would overflow f32 at r = 0.
        (
            "pbf.scorr_dq",
            PbfParams {
                scorr_n: 16,
                scorr_dq: 0.95,
                ..scorr
            },
        ),
        (
            "pbf.vorticity",
            PbfParams {
                vorticity: -1.0,
                ..d
            },
        ),
        (
            "pbf.vorticity",
            PbfParams {
                vorticity: f32::NAN,
                ..d
            },
        ),
        (
            "pbf.over_relaxation",
            PbfParams {
                over_relaxation: 0.0,
                ..d
            },
        ),
        (
            "pbf.over_relaxation",
            PbfParams {
                over_relaxation: 2.0,
                ..d
            },
        ),
        (
            "pbf.over_relaxation",
            PbfParams {
                over_relaxation: f32::NAN,
                ..d
            },
        ),
        (
            "pbf.sleep_speed",
            PbfParams {
                sleep_speed: -0.01,
                ..d
            },
        ),
        // The warm start: out of [0, 0.5], NaN, and under Jacobi, which
        // does not read it.
        (
            "pbf.warm_start",
            PbfParams {
                solve: PbfSolve::GaussSeidel,
                warm_start: 0.6,
                ..d
            },
        ),
        (
            "pbf.warm_start",
            PbfParams {
                solve: PbfSolve::GaussSeidel,
                warm_start: -0.1,
                ..d
            },
        ),
        (
            "pbf.warm_start",
            PbfParams {
                solve: PbfSolve::GaussSeidel,
                warm_start: f32::NAN,
                ..d
            },
        ),
        (
            "pbf.warm_start",
            PbfParams {
                warm_start: 0.5,
                ..d
            },
        ),
        // The surface target, which Jacobi's jitter blows up.
        (
            "pbf.surface_target",
            PbfParams {
                surface_target: true,
                ..d
            },
        ),
        // s_corr, which the Gauss–Seidel sweeps do not apply.
        (
            "pbf.scorr_k",
            PbfParams {
                solve: PbfSolve::GaussSeidel,
                scorr_k: 0.05,
                ..d
            },
        ),
        (
            "pbf.sleep_speed",
            PbfParams {
                sleep_speed: f32::NAN,
                ..d
            },
        ),
        ("pbf.xsph", PbfParams { xsph: 2.0, ..d }),
        (
            "pbf.xsph",
            PbfParams {
                xsph: f32::NAN,
                ..d
            },
        ),
        (
            "pbf.max_displacement",
            PbfParams {
                max_displacement: 0.0,
                ..d
            },
        ),
        (
            "pbf.max_displacement",
            PbfParams {
                max_displacement: 5.0,
                ..d
            },
        ),
        // The implicit solve's ranges, under the implicit viscosity (under
        // XSPH any value away from the default is refused as unread).
        (
            "pbf.viscosity_tolerance",
            PbfParams {
                viscosity_tolerance: 0.0,
                ..implicit
            },
        ),
        (
            "pbf.viscosity_tolerance",
            PbfParams {
                viscosity_tolerance: f32::NAN,
                ..implicit
            },
        ),
        (
            "pbf.viscosity_max_iterations",
            PbfParams {
                viscosity_max_iterations: 0,
                ..implicit
            },
        ),
    ];
    // The fields refused as unread above are accepted where they are read.
    for read in [
        PbfParams {
            scorr_n: 2,
            scorr_dq: 0.3,
            ..scorr
        },
        PbfParams {
            viscosity_tolerance: 1e-4,
            viscosity_max_iterations: 20,
            ..implicit
        },
        PbfParams { xsph: 0.1, ..d },
    ] {
        read.validate().unwrap();
    }
    for (name, p) in cases {
        match p.validate() {
            Err(Error::InvalidParameter { name: got, .. }) => assert_eq!(got, name, "{p:?}"),
            other => panic!("{p:?}: {other:?}"),
        }
        // The same through World and a scene.
        let mut scene = Scene::dam_break(0.1, 0.04, 0.02).with_solver(SolverKind::Pbf);
        scene.solver.pbf = Some(p);
        let e = scene.build_world().unwrap_err().to_string();
        assert!(e.contains(&format!("solver.{name}")), "{e}");
    }
    // A max_dt valid alone that the scene's frame would cut into more than
    // 1000 substeps (16,667 at 60 Hz): refused with the scene, and a frame
    // of a world that long refused before any substep.
    let mut scene = Scene::dam_break(0.1, 0.04, 0.02).with_solver(SolverKind::Pbf);
    scene.solver.pbf = Some(PbfParams { max_dt: 1e-6, ..d });
    let e = scene.build_world().unwrap_err().to_string();
    assert!(e.contains("solver.pbf.max_dt") && e.contains("1000"), "{e}");
    scene.solver.pbf = Some(d);
    let mut world = scene.build_world().unwrap();
    for frame in [10.0, 1e30] {
        match world.advance(frame) {
            Err(Error::InvalidParameter { name, .. }) => assert_eq!(name, "pbf.max_dt"),
            other => panic!("{frame}: {other:?}"),
        }
    }
    assert_eq!(world.time(), 0.0);
    // In a file.
    let mut scene = Scene::dam_break(0.1, 0.04, 0.02).with_solver(SolverKind::Pbf);
    scene.solver.pbf = Some(PbfParams::default());
    let mut text = scene.to_toml();
    text = text.replace("iterations = 3", "iterations = 0");
    let e = Scene::from_toml(&text).unwrap_err().to_string();
    assert!(e.contains("solver.pbf.iterations"), "{e}");
    let e = Scene::from_toml(&text.replace("kind = \"pbf\"", "kind = \"sph\"")).unwrap_err();
    assert!(matches!(e, Error::SceneSyntax(_)), "{e}");
    let bogus = text.replace("viscosity = \"xsph\"", "viscosity = \"honey\"");
    assert_ne!(bogus, text);
    let e = Scene::from_toml(&bogus).unwrap_err().to_string();
    assert!(e.contains("viscosity") && e.contains("implicit"), "{e}");
    // A file without [solver], or without its kind, runs PBF, as the
    // demo's built-in scenes do; a file that wants WCSPH says so.
    let plain = Scene::dam_break(0.1, 0.04, 0.02).to_toml();
    assert!(plain.contains("kind = \"wcsph\""), "{plain}");
    assert_eq!(
        Scene::from_toml(&plain).unwrap().solver.kind,
        SolverKind::Wcsph
    );
    let start = plain.find("[solver").unwrap();
    let end = plain[start..]
        .find("[render]")
        .map_or(plain.len(), |e| start + e);
    let without = format!("{}{}", &plain[..start], &plain[end..]);
    let no_kind = plain.replace("kind = \"wcsph\"", "");
    for text in [without, no_kind] {
        let scene = Scene::from_toml(&text).unwrap();
        assert_eq!(scene.solver.kind, SolverKind::Pbf);
        assert_eq!(scene.solver(), Solver::Pbf(scene.pbf_params()));
    }
}

/// Particles started on top of each other (a third of the spacing apart)
/// leave a constraint solve of one iteration far above twice the rest
/// density, with no headway: the run stops with `Error::Unstable` and a
/// hint, it does not explode silently.
#[test]
fn a_failed_constraint_solve_stops_the_run() {
    let spacing = 0.02;
    let params = FluidParams::water(2.0 * spacing);
    let mass = params.particle_mass(spacing).unwrap();
    let pbf = PbfParams {
        iterations: 1,
        ..PbfParams::default()
    };
    let particles = common::lattice(6, spacing / 3.0, Vec3::splat(0.2), mass);
    let mut world = unbounded(particles, params, pbf);
    match world.advance(1.0 / 60.0) {
        Err(Error::Unstable { what, hint, .. }) => {
            assert!(what.contains("density constraint solve diverged"), "{what}");
            assert!(hint.contains("solver.pbf.iterations"), "{hint}");
        }
        other => panic!("{other:?}"),
    }
}

/// A user's processor plugs into the PBF program at the same station as into
/// WCSPH's (after `forces`): a uniform push of 1 m/s² on a weightless free
/// cluster adds exactly M a t of momentum, since the solve's corrections
/// add none.
#[test]
fn a_user_processor_after_forces_acts_in_pbf() {
    let spacing = 0.02;
    let mut params = FluidParams::water(2.0 * spacing);
    params.gravity = Vec3::ZERO;
    let mass = params.particle_mass(spacing).unwrap();
    let pbf = PbfParams {
        vorticity: 0.0,
        ..PbfParams::default()
    };
    let mut world = unbounded(common::lattice(5, spacing, Vec3::ZERO, mass), params, pbf);
    let push = sph_core::solver::ExternalAcceleration::new("push", |_, _| Vec3::X);
    assert!(world.program_mut().insert_after("forces", push));
    for _ in 0..30 {
        world.advance(1.0 / 60.0).unwrap();
    }
    let p = &world.particles;
    let momentum: f64 = (p.masses().iter().zip(p.velocities()))
        .map(|(&m, v)| f64::from(m) * f64::from(v.x))
        .sum();
    let expected = p.total_mass() * world.time();
    assert!(
        (momentum - expected).abs() < 1e-4 * expected,
        "{momentum} vs {expected}"
    );
}

/// Without a `[solver.pbf]` table a scene derives PBF's substeps from its
/// fluid's height and particle size: 3 per 60 Hz frame for the demo's dam
/// break (h = 0.04 m), 5 for `dam-break-fine` (h = 0.02 m), every substep
/// at most 0.6 h of a fall from the column's top.
#[test]
fn scenes_without_a_pbf_table_derive_their_substeps() {
    for (spacing, substeps) in [(0.02, 3), (0.01, 5)] {
        let scene = Scene::dam_break(0.25, 0.08, spacing).with_solver(SolverKind::Pbf);
        assert_eq!(scene.solver.pbf, None);
        let p = scene.pbf_params();
        assert_eq!(p.substeps, substeps, "spacing {spacing}");
        assert!((p.max_dt - scene.time_step.frame_dt / substeps as f32).abs() < 1e-9);
        let fall = (2.0 * 9.81f32 * 0.5).sqrt() * p.max_dt;
        assert!(
            fall <= sph_core::solver::pbf::FALL_CFL * scene.fluid.h,
            "{fall}"
        );
        assert_eq!(scene.solver(), Solver::Pbf(p));
        // A table, even a partial one, is taken as it stands.
        let text = format!("{}\n[solver.pbf]\niterations = 5\n", scene.to_toml());
        let loaded = Scene::from_toml(&text).unwrap();
        let expected = PbfParams {
            iterations: 5,
            ..PbfParams::default()
        };
        assert_eq!(loaded.pbf_params(), expected);
    }
}

/// The neighbour lists a processor sees are the step's own: none before the
/// `neighbours` station (last step's lists are kept only as memory), one
/// list per particle after it.
#[test]
fn processors_see_only_this_steps_neighbour_lists() {
    use sph_core::{Context, Processor, Result};
    use std::sync::Arc;
    use std::sync::atomic::{AtomicU32, Ordering};
    struct Expect(&'static str, bool, Arc<AtomicU32>);
    impl Processor for Expect {
        fn name(&self) -> &str {
            self.0
        }
        fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
            match &ctx.neighbours {
                Some(lists) => assert!(self.1 && lists.len() == particles.len(), "{}", self.0),
                None => assert!(!self.1, "{}: no lists", self.0),
            }
            self.2.fetch_add(1, Ordering::Relaxed);
            Ok(())
        }
    }
    let scene = Scene::dam_break(0.1, 0.04, 0.02).with_solver(SolverKind::Pbf);
    let mut world = scene.build_world().unwrap();
    let (before, after) = (Arc::default(), Arc::default());
    let program = world.program_mut();
    assert!(program.insert_after("predict", Expect("before", false, Arc::clone(&before))));
    assert!(program.insert_after("neighbours", Expect("after", true, Arc::clone(&after))));
    let mut substeps = 0;
    for _ in 0..3 {
        substeps += world.advance(1.0 / 60.0).unwrap().substeps;
    }
    // Both ran, once a substep: the checks above were made.
    assert_eq!(substeps, 9);
    assert_eq!(before.load(Ordering::Relaxed), substeps);
    assert_eq!(after.load(Ordering::Relaxed), substeps);
}

/// Surface tension under PBF (Akinci et al.'s forces for water's σ): a
/// weightless drop of 4,032 particles (R = 9.9 spacings of 5 mm) stretched
/// along x oscillates in Rayleigh's l = 2 mode at his period 2π/ω,
/// ω² = 8σ/(ρR³), within 10 %. One drop's period moves by several per cent
/// with rounding-level changes (its swing is damped within two periods and
/// the particles jitter), so the median of three stretches (8, 10 and 12 %)
/// is held to it. Measured (sorted): 0.969, 1.019 and 1.047 of Rayleigh's.
#[test]
fn a_drop_oscillates_at_rayleighs_period() {
    let pbf = Solver::Pbf(PbfParams::default());
    let mut ratios: Vec<f64> = [1.08f32, 1.10, 1.12]
        .map(|stretch| common::drop_period(pbf, 0.005, stretch, 6.0))
        .to_vec();
    ratios.sort_by(f64::total_cmp);
    println!("period / Rayleigh's: {ratios:.3?}");
    assert!((ratios[1] - 1.0).abs() <= 0.1, "{ratios:?}");
}

/// Rayleigh's l = 4 mode under PBF, at small amplitude
/// (`common::drop_l4_period`: the lattice sphere moved by the mode's own
/// flow, `eps` R at the surface), its period from a damped-sinusoid fit,
/// the median of `eps` = 0.08, 0.10 and 0.12, as swung (damped) and as the
/// restoring force alone would swing it (undamped: 2π/√(ω² + β²); the
/// swing decays at 1–3 1/s, 10–30 × Lamb's). Measured, damped / undamped
/// medians: 1.248 / 1.227 of Rayleigh's period at 5 mm (R = 5 h), 1.085 /
/// 1.041 at 2.5 mm (10 h); with the paper's equal weights of cohesion and
/// curvature (`surface_tension::COHESION_WEIGHT` = 1, scale 13) they were
/// 1.482 / 1.431 and 1.101 / 1.026 (and 1.263 / 1.179 at 3.5 mm, 1.158 /
/// 1.076 at 2 mm). Held: at 2.5 mm the undamped period within issue 42's
/// 10 % and the damped one within 20 %; at 5 mm the damped one within
/// 30 %, and at least 0.1 longer than at 2.5 mm.
///
/// A second resolution, 2 mm (R = 25 spacings, 64k particles), one
/// amplitude (0.1): measured 1.082 damped, 1.033 undamped; held as at
/// 2.5 mm. (At 3.5 mm, R = 14 spacings, it reads 1.152 and 1.124: l = 4
/// needs R ≥ 20 spacings under PBF.)
#[test]
fn a_drop_rings_near_rayleighs_l4_period_when_resolved() {
    let pbf = Solver::Pbf(PbfParams::default());
    let median = |spacing, across| common::drop_l4_medians(pbf, spacing, across);
    let (coarse, fine) = (median(0.005, 16), median(0.0025, 32));
    assert!((0.8..=1.2).contains(&fine.0), "2.5 mm: {fine:?}");
    assert!((0.9..=1.1).contains(&fine.1), "2.5 mm: {fine:?}");
    assert!((0.7..=1.3).contains(&coarse.0), "5 mm: {coarse:?}");
    assert!(coarse.0 - fine.0 >= 0.1, "5 mm {coarse:?}, 2.5 mm {fine:?}");
    let finer = common::drop_l4_period(pbf, 0.002, 40, 0.1, 3.0);
    println!("0.002 m: period / Rayleigh's, damped and undamped {finer:.3?}");
    assert!((0.8..=1.2).contains(&finer.0), "2 mm: {finer:?}");
    assert!((0.9..=1.1).contains(&finer.1), "2 mm: {finer:?}");
}

/// Rayleigh's period is the small-amplitude limit: a drop far from round
/// swings slower. An inviscid drop in l = 4 at amplitude +0.2 and −0.2
/// swings at 1.065 and 1.084 of Rayleigh's period by its turns
/// (`common::inviscid_drop`, potential flow at finite amplitude from the
/// same start, checked in `tests/inviscid_drop.rs`). PBF's drop at 2.5 mm
/// (R = 20 spacings), read the same way over 3 s: measured 1.054 and 1.077,
/// where at ε = 0.05 it reads 0.973 (`rayleigh_drop -- pbf 3 --shape l4
/// --eps E --spacing 0.0025 --across 32`). Held: each within 4 % of the
/// inviscid drop's, which a drop that kept Rayleigh's period at every
/// amplitude would miss.
#[test]
fn a_large_drop_swings_as_slowly_as_an_inviscid_one() {
    let pbf = Solver::Pbf(PbfParams::default());
    for eps in [0.2f32, -0.2] {
        let inviscid = common::inviscid_drop::period(4, f64::from(eps));
        let ratio = common::drop_l4_turns(pbf, 0.0025, 32, eps, 3.0);
        println!("eps {eps}: period / Rayleigh's {ratio:.3}, the inviscid drop's {inviscid:.3}");
        assert!(
            (ratio / inviscid - 1.0).abs() <= 0.04,
            "eps {eps}: {ratio:.3}"
        );
    }
}

/// Gauss–Seidel's columns keep threads apart only for neighbour lists of
/// the fluid's h: a program whose grid and lists are of another radius
/// is refused by the density station, not run with two threads writing
/// one particle. (Jacobi reads such lists without harm to memory.)
#[test]
fn gauss_seidel_refuses_lists_of_another_radius() {
    use sph_core::solver::BuildGrid;
    use sph_core::solver::pbf::FindNeighbours;
    let mut scene = Scene::dam_break(0.16, 0.08, 0.02).with_solver(SolverKind::Pbf);
    scene.solver.pbf = Some(PbfParams {
        solve: PbfSolve::GaussSeidel,
        ..scene.pbf_params()
    });
    let mut world = scene.build_world().unwrap();
    world.advance(1.0 / 60.0).unwrap();
    let wide = 2.0 * scene.fluid.h;
    let program = world.program_mut();
    assert!(program.remove("grid") && program.remove("neighbours"));
    assert!(program.insert_before("density", BuildGrid::new(wide, 1)));
    assert!(program.insert_before("density", FindNeighbours::new(wide)));
    match world.advance(1.0 / 60.0) {
        Err(Error::Pipeline { processor, reason }) => {
            assert_eq!(processor, "density");
            assert!(reason.contains("gauss-seidel"), "{reason}");
        }
        other => panic!("expected the density station to refuse: {other:?}"),
    }
}
