//! The SPH solver against physics: hydrostatics, momentum and mass conservation,
//! containment and the dam-break front speed, and determinism across threads.

mod common;

use glam::Vec3;
use sph_core::scene::WcsphSpec;
use sph_core::{
    Aabb, Boundary, Context, Error, FluidParams, Particles, Processor, Scene, SolverKind,
    TimeStepping, World,
};

fn momentum(p: &Particles) -> [f64; 3] {
    let mut m = [0.0f64; 3];
    for (&mass, v) in p.masses().iter().zip(p.velocities()) {
        for a in 0..3 {
            m[a] += mass as f64 * v[a] as f64;
        }
    }
    m
}

/// Deterministic pseudo-random numbers in [-1, 1).
fn noise(seed: &mut u64) -> f32 {
    *seed = seed
        .wrapping_mul(6_364_136_223_846_793_005)
        .wrapping_add(1_442_695_040_888_963_407);
    ((*seed >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
}

/// A free cluster of particles of slightly different masses: momentum is
/// conserved (the symmetric pressure and viscosity forces are pairwise
/// opposite), and after a thousand steps of re-sorting by cell every particle is
/// still there exactly once, with its own mass.
#[test]
fn free_cluster_conserves_momentum_and_mass() {
    let spacing = 0.02;
    let mut params = FluidParams::water(2.0 * spacing);
    params.gravity = Vec3::ZERO;
    params.surface_tension = 0.0; // MCG03 surface tension is not pairwise symmetric
    params.stiffness = 500.0;
    let mass = params.particle_mass(spacing).unwrap();
    let mut particles = Particles::new();
    let mut seed = 7;
    for k in 0..8 {
        for j in 0..8 {
            for i in 0..8 {
                let x = Vec3::new(i as f32, j as f32, k as f32) * spacing
                    + Vec3::new(noise(&mut seed), noise(&mut seed), noise(&mut seed))
                        * 0.2
                        * spacing;
                let v = Vec3::new(noise(&mut seed), noise(&mut seed), noise(&mut seed)) * 0.5;
                particles.push(x, v, mass * (1.0 + 0.02 * noise(&mut seed)));
            }
        }
    }
    let mass_of = |p: &Particles| {
        let mut by_id: Vec<(u64, f32)> = p
            .ids()
            .iter()
            .copied()
            .zip(p.masses().iter().copied())
            .collect();
        by_id.sort_by_key(|&(id, _)| id);
        by_id
    };
    let m0 = mass_of(&particles);
    let p0 = momentum(&particles);
    let scale: f64 = particles
        .masses()
        .iter()
        .zip(particles.velocities())
        .map(|(&m, v)| m as f64 * v.length() as f64)
        .sum();
    // Walls far beyond reach: nothing but internal forces acts.
    let boundary = Boundary::new(Aabb::new(Vec3::splat(-100.0), Vec3::splat(100.0)));
    let mut world = World::new(particles, params, boundary, TimeStepping::default()).unwrap();
    for _ in 0..1000 {
        world.step().unwrap();
    }
    let p1 = momentum(&world.particles);
    let drift =
        ((p1[0] - p0[0]).powi(2) + (p1[1] - p0[1]).powi(2) + (p1[2] - p0[2]).powi(2)).sqrt();
    println!("momentum drift {drift:e} of Σ m|v| = {scale:e} after 1000 steps");
    assert!(
        drift <= 1e-5 * scale,
        "momentum drift {drift:e} vs Σ m|v| {scale:e}"
    );
    // The solver keeps the particles in cell order; none is lost, duplicated
    // or given another's mass on the way.
    let ids = world.particles.ids();
    assert!(ids.windows(2).any(|w| w[0] > w[1]), "the solver re-sorted");
    assert_eq!(mass_of(&world.particles), m0, "particles or masses changed");
    assert_eq!(m0.len(), 512);
}

/// Surface tension (eq. 18–20) pulls a weightless cube of fluid towards a
/// sphere: its corners, where the surface curves most, move in, while without
/// it they stay put. A flipped sign would push them out.
#[test]
fn surface_tension_rounds_a_cube() {
    let corner_reach = |sigma: f32| {
        let spacing = 0.02;
        let mut params = FluidParams::water(2.0 * spacing);
        params.gravity = Vec3::ZERO;
        params.surface_tension = sigma;
        let mass = params.particle_mass(spacing).unwrap();
        let mut particles = Particles::new();
        for k in 0..10 {
            for j in 0..10 {
                for i in 0..10 {
                    let x = (Vec3::new(i as f32, j as f32, k as f32) - 4.5) * spacing;
                    particles.push(x, Vec3::ZERO, mass);
                }
            }
        }
        let reach = |p: &Particles| {
            let c = p.positions().iter().sum::<Vec3>() / p.len() as f32;
            (p.positions().iter()).fold(0.0f32, |r, x| r.max((*x - c).length()))
        };
        let before = reach(&particles);
        let boundary = Boundary::new(Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0)));
        let mut world = World::new(particles, params, boundary, TimeStepping::default()).unwrap();
        for _ in 0..10 {
            world.advance(0.01).unwrap();
        }
        reach(&world.particles) / before
    };
    let (still, rounded) = (corner_reach(0.0), corner_reach(2.0));
    println!(
        "corner distance after 0.1 s: ×{still:.4} without surface tension, ×{rounded:.4} with σ = 2 N/m"
    );
    assert!(
        (still - 1.0).abs() < 0.01,
        "without surface tension: ×{still}"
    );
    assert!(rounded < 0.97, "with surface tension: ×{rounded}");
}

/// A tank of water at rest settles: density, the hydrostatic pressure gradient,
/// rest, and an energy that never rises (nothing drives the tank).
#[test]
fn hydrostatic_tank() {
    let spacing = 0.02;
    let h = 2.0 * spacing;
    let (w, depth) = (0.4f32, 0.4f32);
    let mut scene = Scene::dam_break(w, w, spacing);
    scene.domain.max = [w, 0.6, w];
    scene.blocks[0].max = [w, depth, w];
    scene.solver.wcsph = Some(WcsphSpec {
        stiffness: 500.0,
        ..WcsphSpec::default()
    });
    scene.fluid.viscosity = Some(1.0);
    let mut world = scene.build_world().unwrap();
    // Total energy per particle mass: kinetic + gravitational + the equation of
    // state's pressure energy u(ρ) = k (ln(ρ/ρ0) + ρ0/ρ − 1) for ρ > ρ0.
    let (k, rho0) = (
        scene.wcsph_params().stiffness as f64,
        scene.fluid.rest_density as f64,
    );
    let energy = |p: &Particles| -> f64 {
        let mut e = 0.0;
        for i in 0..p.len() {
            let r = p.densities()[i] as f64 / rho0;
            e += 0.5 * p.velocities()[i].length_squared() as f64
                + 9.81 * p.positions()[i].y as f64
                + if r > 1.0 {
                    k * (r.ln() + 1.0 / r - 1.0)
                } else {
                    0.0
                };
        }
        e / p.len() as f64
    };
    world.step().unwrap();
    let mut energies = vec![energy(&world.particles)];
    while world.time() < 1.5 {
        world.step().unwrap();
        if world.time() >= 0.1 * energies.len() as f64 {
            energies.push(energy(&world.particles));
        }
    }
    println!("energy (J/kg) every 0.1 s: {energies:.4?}");
    for w in energies.windows(2) {
        assert!(
            w[1] <= w[0] + 1e-3 * energies[0],
            "energy rose: {energies:?}"
        );
    }
    let p = &world.particles;
    let top = p.positions().iter().map(|x| x.y).fold(f32::MIN, f32::max);
    // Interior: more than h from the side walls, the floor and the free surface.
    let interior: Vec<usize> = (0..p.len())
        .filter(|&i| {
            let x = p.positions()[i];
            x.x > h && x.x < w - h && x.z > h && x.z < w - h && x.y > h && x.y < top - h
        })
        .collect();
    assert!(
        interior.len() > 1000,
        "{} interior particles",
        interior.len()
    );
    let density_error = interior
        .iter()
        .map(|&i| (p.densities()[i] as f64 - rho0).abs() / rho0)
        .sum::<f64>()
        / interior.len() as f64;
    // Least-squares slope of pressure against depth, and against the weight
    // of the fluid above (`common::pressures_and_weights_above`: near the
    // free surface the layers sit closer than in the bulk, which a slope
    // over depth reads as pressure).
    let slope = common::slope(interior.iter().map(|&i| {
        let d = f64::from(top - p.positions()[i].y);
        (d, f64::from(p.pressures()[i]))
    }));
    let rho_g = rho0 * 9.81;
    let weighed =
        common::slope(common::pressures_and_weights_above(p, 9.81, w, spacing, h, h).into_iter());
    let rms_speed = (p
        .velocities()
        .iter()
        .map(|v| v.length_squared() as f64)
        .sum::<f64>()
        / p.len() as f64)
        .sqrt();
    println!(
        "density error {:.3} %, dp/d(depth) = {slope:.1} Pa/m vs ρ0 g = {rho_g:.1} ({:+.2} %), \
         pressure over the weight above {weighed:.4}, rms speed {rms_speed:.4} m/s",
        100.0 * density_error,
        100.0 * (slope - rho_g) / rho_g
    );
    assert!(density_error < 0.03, "mean density error {density_error}");
    // Measured −0.72 % with the scenes' default clearance (−2.08 % while the
    // walls' layers were V^⅓ apart, −1.23 % without a clearance). Against
    // the weight of the fluid above, the same pressures read 0.886 (0.874
    // before): this stiffness lets the column settle far below its filled
    // depth (at 0.874, 13 %: the 99th percentile of heights 0.346 m of 0.4,
    // about 1,130 kg/m³ of particle mass per volume), while the poly6
    // density reads 0.37 % above ρ0. The printed ratio is that
    // compression's measure; the slope over depth is what the pressure
    // force balances.
    assert!(
        (slope - rho_g).abs() < 0.025 * rho_g,
        "slope {slope} vs ρ0 g {rho_g}"
    );
    // 2.5 % of the free-fall speed √(g·depth) ≈ 2 m/s.
    assert!(rms_speed < 0.05, "rms speed {rms_speed} m/s");
    // Where the floor meets a side wall the two walls' density terms overlap
    // (see `sph_core::boundary`): the edge must not empty out or overfill.
    // Particles and mean density in a 2h × h channel along the edge, and in
    // one on the floor away from the walls (2h wide, so that where the
    // settled layers fall matters less).
    let channel = |x0: f32| {
        let inside: Vec<usize> = (0..p.len())
            .filter(|&i| {
                let x = p.positions()[i];
                (x0..x0 + 2.0 * h).contains(&x.x) && x.y < h && x.z > h && x.z < w - h
            })
            .collect();
        let rho = inside.iter().map(|&i| p.densities()[i] as f64).sum::<f64>();
        (inside.len(), rho / inside.len().max(1) as f64)
    };
    let ((edge, edge_rho), (floor, floor_rho)) = (channel(0.0), channel(0.5 * w - h));
    println!(
        "floor–wall edge: {edge} particles, mean ρ {edge_rho:.1}; floor alone: {floor}, {floor_rho:.1}"
    );
    // (Layering along the walls makes the counts differ by some 10 %; a
    // void at the edge would show as far fewer.)
    assert!(
        edge as f64 > 0.75 * floor as f64,
        "{edge} particles at the edge, {floor} on the floor"
    );
    assert!(
        (edge_rho - floor_rho).abs() < 0.01 * rho0,
        "mean density {edge_rho} at the edge, {floor_rho} on the floor"
    );
}

#[test]
fn dam_break_soak_stays_contained_and_subcritical() {
    let (a, spacing) = (0.2f32, 0.02f32);
    let scene = Scene::dam_break(a, 3.0 * spacing, spacing);
    let boundary = scene.boundary();
    let mut world = scene.build_world().unwrap();
    let front = |w: &World| {
        w.particles
            .positions()
            .iter()
            .map(|x| x.x)
            .fold(f32::MIN, f32::max)
    };
    let front0 = front(&world);
    let ritter = 2.0 * (9.81f32 * 2.0 * a).sqrt();
    let mut fastest = 0.0f32;
    for step in 0..20_000 {
        world.step().unwrap();
        let t = world.time() as f32;
        // Until the front reaches the far wall, compare with Ritter's dry-bed speed.
        let f = front(&world);
        if f < scene.domain.max[0] - scene.fluid.h {
            fastest = fastest.max((f - front0 - scene.fluid.h) / t);
            assert!(
                f - front0 <= ritter * t + scene.fluid.h,
                "step {step}: front moved {} m in {t} s, Ritter allows {}",
                f - front0,
                ritter * t
            );
        }
        if step % 1000 == 0 || step == 19_999 {
            let outside = world
                .particles
                .positions()
                .iter()
                .filter(|&&x| !boundary.admits(x))
                .count();
            assert_eq!(outside, 0, "step {step}: particles outside the domain");
        }
    }
    assert!(world.particles.positions().iter().all(|x| x.is_finite()));
    // And it does run out: measured 0.461 of Ritter's ideal (frictionless,
    // dry-bed) speed, which experiments also stay below (Martin & Moyce's
    // front averages 0.47 of it to Z = 4, where this tank ends: see
    // `tests/dam_break_experiment.rs`); asserted within 0.05 of that. It
    // read 0.495 while the walls' layers were V^⅓ apart, and 0.727 before
    // the walls continued the lattice under the clearance: the first step kicked the column's over-dense wall and
    // corner particles ahead of the front.
    assert!(
        (fastest / ritter - 0.461).abs() <= 0.05,
        "the front moved at most {fastest} m/s, Ritter {ritter} m/s"
    );
    println!(
        "{} particles, {} steps, t = {:.3} s; front speed (minus h) at most {fastest:.3} m/s vs Ritter {ritter:.3} m/s",
        world.particles.len(),
        world.steps(),
        world.time()
    );
}

/// Bitwise the same particles for 1, 2, 3, 4 and 7 threads: a small dam
/// break over 200 steps, and one of 70,000 particles, past the 2 × 32,768 at
/// which the grid's counting sort splits its input by thread, over 5 steps.
#[test]
fn identical_for_1_2_3_4_and_7_threads() {
    identical_runs(&Scene::dam_break(0.16, 0.08, 0.02), 200);
    let large = Scene::dam_break(0.5, 0.14, 0.01);
    assert!(large.particles().unwrap().len() > 65_536);
    identical_runs(&large, 5);
}

fn identical_runs(scene: &Scene, steps: usize) {
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let mut world = scene.build_world().unwrap();
                for _ in 0..steps {
                    world.step().unwrap();
                }
                let p = &world.particles;
                let bits = |v: &[Vec3]| {
                    v.iter()
                        .flat_map(|x| x.to_array().map(f32::to_bits))
                        .collect::<Vec<_>>()
                };
                (
                    p.ids().to_vec(),
                    bits(p.positions()),
                    bits(p.velocities()),
                    world.time().to_bits(),
                )
            })
    };
    let one = run(1);
    for threads in [2, 3, 4, 7] {
        assert!(one == run(threads), "{threads} threads differ from 1");
    }
}

/// Regression: `advance` used to end a frame with a sliver substep (frame time
/// minus the stable steps) and reject it as "below min_dt"; this scene at 30
/// frames/s died at t = 0.467 s.
#[test]
fn frames_end_without_sliver_steps() {
    let mut world = Scene::dam_break(0.25, 0.08, 0.02).build_world().unwrap();
    let mut smallest = f32::INFINITY;
    for frame in 1..=18 {
        let report = world.advance(1.0 / 30.0).unwrap();
        smallest = smallest.min(report.dt_range.0);
        assert_eq!(world.time(), report.time);
        assert!(
            (report.time - frame as f64 / 30.0).abs() < 1e-6,
            "t = {}",
            report.time
        );
    }
    // The shortest substep is at least half a typical one, never a sliver
    // (the stable step itself changes a little within a frame).
    let mut world = Scene::dam_break(0.25, 0.08, 0.02).build_world().unwrap();
    for _ in 0..18 {
        let (shortest, longest) = world.advance(1.0 / 30.0).unwrap().dt_range;
        assert!(
            shortest >= 0.45 * longest,
            "substeps {shortest:e}..{longest:e} s"
        );
    }
}

/// Asserts the world's next step fails in the density processor, with a
/// message saying `why`.
fn density_refuses(world: &mut World, why: &str) {
    let e = world.step().unwrap_err();
    assert!(
        matches!(
            e,
            Error::Pipeline {
                processor: "density",
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains(why), "{e}");
}

/// A processor that adds particles after the grid was built, without
/// `Context::invalidate_grid`, gets an error from the next gather, not a panic.
#[test]
fn a_stale_grid_is_an_error() {
    struct Sneak;
    impl Processor for Sneak {
        fn name(&self) -> &str {
            "sneak"
        }
        fn process(&mut self, particles: &mut Particles, _: &mut Context) -> sph_core::Result<()> {
            particles.push(Vec3::splat(0.1), Vec3::ZERO, 1.0);
            Ok(())
        }
    }
    let mut world = Scene::dam_break(0.1, 0.04, 0.02).build_world().unwrap();
    assert!(world.program_mut().insert_after("grid", Sneak));
    density_refuses(&mut world, "invalidate_grid");
}

/// A particle too light for h added after the world was built (here by a
/// processor) stops DFSPH's next step with an error naming it, where its
/// Jacobi relaxation summed over (h/V^⅓)³ neighbour offsets and never
/// ended.
#[test]
fn a_light_particle_added_later_is_an_error() {
    struct Light;
    impl Processor for Light {
        fn name(&self) -> &str {
            "light"
        }
        fn process(
            &mut self,
            particles: &mut Particles,
            ctx: &mut Context,
        ) -> sph_core::Result<()> {
            particles.push(Vec3::splat(0.05), Vec3::ZERO, 1e-20);
            ctx.invalidate_grid();
            Ok(())
        }
    }
    let scene = Scene::dam_break(0.1, 0.04, 0.02).with_solver(SolverKind::Dfsph);
    let mut world = scene.build_world().unwrap();
    assert!(world.program_mut().insert_before("grid", Light));
    let e = world.step().unwrap_err();
    assert!(e.to_string().contains("too light for h"), "{e}");
}

/// Particles a simulation cannot run are errors naming the particle, before
/// any step (a zero mass used to surface as an `Unstable` NaN with a hint
/// about time steps), and a grid built for another h than the fluid's is a
/// pipeline error, not a panic or forces for the wrong h.
#[test]
fn bad_particles_and_a_grid_of_another_h_are_errors() {
    let scene = Scene::dam_break(0.1, 0.04, 0.02);
    let good = scene.particles().unwrap();
    let bad = |x: Vec3, v: Vec3, m: f32| {
        let mut p = good.clone();
        p.push(x, v, m);
        scene.world_with(p).unwrap_err()
    };
    let x = Vec3::splat(0.05);
    let m = good.masses()[0];
    for mass in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        let e = bad(x, Vec3::ZERO, mass);
        assert!(
            matches!(e, Error::InvalidParticle { what: "mass", index, .. } if index == good.len()),
            "{e}"
        );
    }
    // A particle far lighter than its h's lattice (a volume whose side is
    // under h/10) under every solver, with and without a clearance: DFSPH's
    // relaxation and the walls' layers summed over (h/V^⅓)³ offsets, and
    // at 10⁻²⁰ kg a step never ended.
    for kind in SolverKind::ALL {
        for clearance in [0.0, 0.01] {
            let mut light = scene.clone().with_solver(kind);
            light.clearance = Some(clearance);
            let mut p = light.particles().unwrap();
            p.push(x, Vec3::ZERO, 1e-20);
            let e = light.world_with(p).unwrap_err();
            assert!(
                matches!(e, Error::InvalidParticle { what: "mass", .. })
                    && e.to_string().contains("too light for h"),
                "{kind:?}: {e}"
            );
        }
    }
    // The lattice mass of h/10, the widest neighbourhood a scene may have,
    // passes (the check allows a per cent for the lattice's kernel sum,
    // which makes that mass a little lighter than ρ0 (h/10)³).
    for kind in SolverKind::ALL {
        for ratio in [9.99f32, 10.0] {
            let mut wide = scene.clone().with_solver(kind);
            wide.fluid.h = ratio * wide.spacing;
            if let Err(e) = wide.build_world() {
                panic!("{kind:?} at h = {ratio} spacings: {e}");
            }
        }
    }
    let e = bad(x, Vec3::new(0.0, f32::NAN, 0.0), m);
    assert!(
        matches!(
            e,
            Error::InvalidParticle {
                what: "velocity",
                ..
            }
        ),
        "{e}"
    );
    let e = bad(Vec3::new(f32::INFINITY, 0.0, 0.0), Vec3::ZERO, m);
    assert!(matches!(e, Error::NonFinitePosition { .. }), "{e}");
    // A domain reaching 2^20 h from the origin, where an f32 ulp of a
    // position is h/8: the same particles moved there are refused.
    let offset = Vec3::new(1_048_576.0 * scene.fluid.h, 0.0, 0.0);
    let mut far = Particles::new();
    for (x, v) in good.positions().iter().zip(good.velocities()) {
        far.push(*x + offset, *v, m);
    }
    let b = scene.boundary();
    let boundary = Boundary::new(Aabb::new(b.domain.min + offset, b.domain.max + offset));
    let e = World::with_solver(
        far,
        scene.fluid_params(),
        boundary,
        scene.time_stepping(),
        scene.solver(),
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            Error::InvalidParameter {
                name: "boundary.domain",
                ..
            }
        ) && e.to_string().contains("65,536 h"),
        "{e}"
    );

    let mut world = scene.world_with(good).unwrap();
    let h = world.params().h;
    assert!(world.program_mut().remove("grid"));
    world
        .program_mut()
        .insert_before("density", sph_core::solver::BuildGrid::new(2.0 * h, 0));
    density_refuses(&mut world, "another h");
}

/// At the largest h and rest density the parameters accept, the density
/// sums stay finite (at h = 1e4 m, then accepted, water's density overflowed
/// f32 at the first step), and the fluid sums to about its rest density.
#[test]
fn largest_h_and_rest_density_stay_finite() {
    use sph_core::error::KERNEL_H_RANGE;
    use sph_core::solver::MAX_REST_DENSITY;
    let h = KERNEL_H_RANGE.1;
    let params = FluidParams {
        rest_density: MAX_REST_DENSITY,
        ..FluidParams::water(h)
    };
    let spacing = 0.5 * h;
    let mass = params.particle_mass(spacing).unwrap();
    let mut particles = Particles::new();
    for i in 0..6 {
        for j in 0..6 {
            for k in 0..6 {
                let x = Vec3::new(i as f32, j as f32, k as f32) * spacing;
                particles.push(x, Vec3::ZERO, mass);
            }
        }
    }
    let domain = Aabb::new(Vec3::splat(-10.0 * h), Vec3::splat(10.0 * h));
    let mut world = World::new(
        particles,
        params,
        Boundary::new(domain),
        TimeStepping::default(),
    )
    .unwrap();
    world.step().unwrap();
    let rho = world.particles.densities();
    let inner = rho.iter().copied().fold(0.0f32, f32::max);
    assert!(rho.iter().all(|r| r.is_finite() && *r > 0.0));
    assert!(
        (inner / MAX_REST_DENSITY - 1.0).abs() < 0.05,
        "densest particle {inner} kg/m³"
    );
    let denser = FluidParams {
        rest_density: 2.0 * MAX_REST_DENSITY,
        ..params
    };
    assert!(denser.validate().is_err());
}

/// Parameters that pass one by one but cannot run together are errors up
/// front: a largest step below the blow-up threshold, and a lattice so fine
/// for h that finding the particle mass alone would take minutes.
#[test]
fn inconsistent_parameters_are_errors() {
    let stepping = TimeStepping {
        max_dt: 1e-9,
        ..TimeStepping::default()
    };
    let e = stepping.validate().unwrap_err().to_string();
    assert!(e.contains("max_dt") && e.contains("min_dt"), "{e}");
    let fluid = FluidParams::water(0.04);
    assert!(fluid.particle_mass(0.02).is_ok());
    assert!(fluid.particle_mass(0.004).is_ok());
    let e = fluid.particle_mass(0.0039).unwrap_err().to_string();
    assert!(e.contains("at most 10"), "{e}");
    // A boundary a program would run wrongly with, built by hand (scenes
    // check theirs): an error from `World::new` and from the processors.
    let water = FluidParams::water(0.04);
    let unit = Aabb::new(Vec3::ZERO, Vec3::ONE);
    let mut bad = Vec::new();
    let mut b = Boundary::new(unit);
    b.restitution = 1.5;
    bad.push(b);
    let mut b = Boundary::new(unit);
    b.obstacles.push(sph_core::Obstacle::Sphere {
        centre: Vec3::splat(0.5),
        radius: -0.1,
    });
    bad.push(b);
    bad.push(Boundary::new(Aabb {
        min: Vec3::ONE,
        max: Vec3::ZERO,
    }));
    for b in bad {
        let e = World::new(Particles::new(), water, b.clone(), TimeStepping::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("boundary"), "{e}");
        assert!(sph_core::solver::Forces::new(water, b.clone()).is_err());
        assert!(sph_core::solver::Boundaries::new(b).is_err());
    }
    // So viscous that its stable step is below the blow-up threshold: every
    // run would stop at step 1 with a hint that cannot help.
    let syrup = FluidParams {
        viscosity: 1e4,
        ..FluidParams::water(1e-3)
    };
    assert!(syrup.viscous_dt() < TimeStepping::default().min_dt);
    let boundary = Boundary::new(Aabb::new(Vec3::ZERO, Vec3::ONE));
    let e = World::new(Particles::new(), syrup, boundary, TimeStepping::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("viscosity") && e.contains("min_dt"), "{e}");
}

/// A very viscous fluid, whose explicit viscosity needs shorter steps than
/// the acoustic CFL condition: at μ = 3000 Pa·s the dam break used to blow up
/// at t = 0.03 s (a particle at 224 m/s); with the viscous limit it runs, and
/// every step keeps to the limit.
#[test]
fn very_viscous_fluid_keeps_to_the_viscous_step_limit() {
    let mut scene = Scene::dam_break(0.2, 0.06, 0.02);
    scene.fluid.viscosity = Some(3000.0);
    let mut world = scene.build_world().unwrap();
    let limit = world.params().viscous_dt();
    let acoustic = 0.4 * world.params().h / world.params().sound_speed();
    assert!(
        limit < 0.5 * acoustic,
        "the limit must bind: {limit} vs {acoustic}"
    );
    let mut longest = 0.0f32;
    for _ in 0..6 {
        let report = world.advance(1.0 / 30.0).unwrap();
        longest = longest.max(report.dt_range.1);
    }
    assert!(longest <= limit, "a step of {longest} s, limit {limit} s");
    assert!(world.particles.positions().iter().all(|x| x.is_finite()));
    let water = FluidParams {
        viscosity: 0.0,
        ..FluidParams::water(0.04)
    };
    assert_eq!(water.viscous_dt(), f32::INFINITY);
}

/// A sink at the far end of the tank removes the fluid that reaches it: after
/// every frame nothing is inside it, and the particles left plus those
/// removed are the ones the run started with, each id once, with their mass.
#[test]
fn sink_removes_what_reaches_it() {
    use std::sync::atomic::Ordering;
    let scene = Scene::dam_break(0.2, 0.06, 0.02);
    let mut world = scene.build_world().unwrap();
    let (start, mass) = (world.particles.len() as u64, world.particles.total_mass());
    let m = world.particles.masses()[0] as f64;
    let region = Aabb::new(Vec3::new(0.6, 0.0, 0.0), Vec3::new(0.8, 0.1, 0.06));
    let sink = sph_core::solver::Sink::new(region);
    let removed = sink.counter();
    world.program_mut().push(sink);
    for _ in 0..30 {
        world.advance(1.0 / 30.0).unwrap();
        let p = &world.particles;
        assert!(p.positions().iter().all(|&x| !region.contains(x)));
        let gone = removed.load(Ordering::Relaxed);
        assert_eq!(p.len() as u64 + gone, start);
        assert!((p.total_mass() + gone as f64 * m - mass).abs() < 1e-9 * mass);
        let mut ids = p.ids().to_vec();
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids.len(), p.len(), "an id twice");
    }
    let gone = removed.load(Ordering::Relaxed);
    println!("the sink removed {gone} of {start} particles in 1 s");
    assert!(
        gone > start / 10,
        "the front never reached the sink: {gone}"
    );
}
