//! Helpers shared by the solver tests. Each test crate compiles this
//! module and uses part of it.

#[allow(dead_code)]
pub mod inviscid_drop;

#[allow(dead_code)]
/// The least-squares slope of y over x for the points (x, y).
pub fn slope(points: impl Iterator<Item = (f64, f64)> + Clone) -> f64 {
    let n = points.clone().count() as f64;
    let (mx, my) = points
        .clone()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (sxy, sxx) = points.fold((0.0, 0.0), |(a, b), (x, y)| {
        (a + (x - mx) * (y - my), b + (x - mx) * (x - mx))
    });
    sxy / sxx
}

#[allow(dead_code)]
/// The least-squares slope of the pressures `ps` over the heights `ys`.
pub fn pressure_slope(ys: &[f32], ps: &[f32]) -> f64 {
    slope(
        ys.iter()
            .zip(ps)
            .map(|(&y, &p)| (f64::from(y), f64::from(p))),
    )
}

/// A square tank at rest read as hydrostatics does: for each particle more
/// than `margin` from the side walls (x and z in (`margin`, `side` −
/// `margin`)) and the floor, and more than `h` below the top layer, the
/// weight per area of the fluid above it (Pa) and its pressure (Pa).
///
/// dp/dy = −ρ g holds with ρ the fluid's mass per volume. Near a free
/// surface SPH's density reads ρ0 with the layers closer together than in
/// the bulk (the kernel's missing neighbours), so a pressure slope over
/// height counts that closeness as excess pressure, and how much of it a
/// fit sees depends on where the surface settled. The weight above does
/// not: it sums the masses of every particle of the tank more than half a
/// `spacing` above this one, and half of those within half a spacing (its
/// own layer), times g over the floor's area `side`². The top layer is the
/// 99th percentile of the heights.
#[allow(dead_code)]
pub fn pressures_and_weights_above(
    p: &sph_core::Particles,
    g: f32,
    side: f32,
    spacing: f32,
    h: f32,
    margin: f32,
) -> Vec<(f64, f64)> {
    let mut layers: Vec<(f32, f64)> = (p.positions().iter().zip(p.masses()))
        .map(|(x, &m)| (x.y, f64::from(m)))
        .collect();
    layers.sort_by(|a, b| a.0.total_cmp(&b.0));
    // mass_above[k]: the mass of the particles from k up.
    let mut mass_above = vec![0.0f64; layers.len() + 1];
    for k in (0..layers.len()).rev() {
        mass_above[k] = mass_above[k + 1] + layers[k].1;
    }
    let above = |y: f32| mass_above[layers.partition_point(|l| l.0 <= y)];
    let top = layers[(0.99 * (layers.len() - 1) as f64) as usize].0;
    let per_area = f64::from(g) / f64::from(side * side);
    let inside = |c: f32| c > margin && c < side - margin;
    (p.positions().iter().zip(p.pressures()))
        .filter(|(x, _)| inside(x.x) && inside(x.z) && x.y > margin && x.y < top - h)
        .map(|(x, &pressure)| {
            let (clear, own) = (above(x.y + 0.5 * spacing), above(x.y - 0.5 * spacing));
            (
                per_area * (clear + 0.5 * (own - clear)),
                f64::from(pressure),
            )
        })
        .collect()
}

/// The l = 2 period of a weightless water drop (σ = 0.0728 N/m, μ = 0.01
/// Pa·s, h = 2 spacings) of 4,032 particles (a sphere of the volume of 16³
/// lattice cells, R ≈ 9.9 spacings) stretched by
/// `stretch` along x, run by `solver` for `seconds`, over Rayleigh's: the
/// mean spacing of the extent's turns (2√5 × the rms offset along x, 2R
/// for a sphere; a turn at least 1 % of 2R from the last).
#[allow(dead_code)]
pub fn drop_period(solver: sph_core::Solver, spacing: f32, stretch: f32, seconds: f64) -> f64 {
    use sph_core::glam::Vec3;
    let scale = Vec3::new(stretch, stretch.powf(-0.5), stretch.powf(-0.5));
    let extent = |x: &[Vec3], c: Vec3, _: f64| {
        let var = x
            .iter()
            .map(|x| f64::from((x.x - c.x).powi(2)))
            .sum::<f64>()
            / x.len() as f64;
        2.0 * (5.0 * var).sqrt()
    };
    let (series, rayleigh, r) =
        drop_oscillation(solver, spacing, 16, 2, |x, _| x * scale, extent, seconds);
    turn_period(&series, 0.02 * r)
        .unwrap_or_else(|| panic!("stretch {stretch}: fewer than 3 turns"))
        / rayleigh
}

/// The period of an oscillating `series` (t, y) from its turns: twice the
/// mean spacing of its local extrema after the start, a turn counting where
/// it lies more than `min_swing` from the last (so that a resting signal's
/// wiggles do not). `None` with fewer than three turns. The first half
/// swing, from the start to the first turn, is left out.
#[allow(dead_code)]
pub fn turn_period(series: &[(f64, f64)], min_swing: f64) -> Option<f64> {
    let (mut turns, mut last) = (Vec::new(), series.first()?.1);
    for w in series.windows(3) {
        let (a, b, c) = (w[0].1, w[1].1, w[2].1);
        if ((b > a && b >= c) || (b < a && b <= c)) && (b - last).abs() > min_swing {
            turns.push(w[1].0);
            last = b;
        }
    }
    (turns.len() >= 3).then(|| 2.0 * (turns[turns.len() - 1] - turns[0]) / (turns.len() - 1) as f64)
}

/// The l = 4 drop of [`drop_l4_period`] at amplitude `eps`, its period read
/// from the amplitude's turns ([`turn_period`], a turn at least 0.01 from
/// the last, as `rayleigh_drop` reads it) over Rayleigh's. For large `eps`,
/// where the inviscid drop itself swings slower than Rayleigh's linear
/// period ([`inviscid_drop`]).
#[allow(dead_code)]
pub fn drop_l4_turns(
    solver: sph_core::Solver,
    spacing: f32,
    across: u32,
    eps: f32,
    seconds: f64,
) -> f64 {
    let (series, rayleigh) = l4_series(solver, spacing, across, eps, seconds);
    turn_period(&series, 0.01).unwrap_or_else(|| panic!("eps {eps}: fewer than 3 turns")) / rayleigh
}

/// The l = 4 amplitude of [`drop_l4_period`]'s drop against time, and
/// Rayleigh's l = 4 period.
fn l4_series(
    solver: sph_core::Solver,
    spacing: f32,
    across: u32,
    eps: f32,
    seconds: f64,
) -> (Vec<(f64, f64)>, f64) {
    use sph_core::glam::Vec3;
    let amplitude = |x: &[Vec3], c: Vec3, r: f64| l4_amplitude(x, c, r);
    let move_point = move |x: Vec3, r: f32| x + eps * r * l4_flow(x / r);
    let (series, rayleigh, _) =
        drop_oscillation(solver, spacing, across, 4, move_point, amplitude, seconds);
    (series, rayleigh)
}

/// The l = 4 period of the same drop at `across`³ cells' volume (R ≈ 0.62
/// `across` spacings), over Rayleigh's, at small amplitude: the lattice
/// points moved by Rayleigh's own l = 4 flow, the gradient of the harmonic
/// r⁴ P₄(cos θ) (divergence-free: the density stays uniform), so that the
/// surface moves out by `eps` R P₄(cos θ). The axis lies where the cubic
/// harmonic x⁴ + y⁴ + z⁴ − 3/5 vanishes (in the xy-plane, ½ asin √0.8 from
/// x), so the cubic lattice's own l = 4 shape does not project on the
/// amplitude measured, 3⟨r⁴ P₄(cos θ)⟩/R⁴ about that axis (0 for the
/// undisturbed lattice sphere, `eps` at the start). The period is the
/// damped sinusoid's that fits the amplitude best ([`damped_fit`]); also
/// returned, the undamped one, 2π/√(ω² + β²), over Rayleigh's.
#[allow(dead_code)]
pub fn drop_l4_period(
    solver: sph_core::Solver,
    spacing: f32,
    across: u32,
    eps: f32,
    seconds: f64,
) -> (f64, f64) {
    let (series, rayleigh) = l4_series(solver, spacing, across, eps, seconds);
    let omega_r = 2.0 * std::f64::consts::PI / rayleigh;
    let (omega, beta) = damped_fit(&series, omega_r).expect("the drop rings");
    (omega_r / omega, omega_r / omega.hypot(beta))
}

/// The medians of [`drop_l4_period`]'s damped and undamped ratios over
/// amplitudes 0.08, 0.10 and 0.12, each sorted set printed.
#[allow(dead_code)]
pub fn drop_l4_medians(solver: sph_core::Solver, spacing: f32, across: u32) -> (f64, f64) {
    let fits = [0.08f32, 0.10, 0.12].map(|eps| drop_l4_period(solver, spacing, across, eps, 3.0));
    let sorted = |mut v: [f64; 3]| {
        v.sort_by(f64::total_cmp);
        v
    };
    let (damped, undamped) = (sorted(fits.map(|f| f.0)), sorted(fits.map(|f| f.1)));
    println!("{spacing} m: period / Rayleigh's, damped {damped:.3?}, undamped {undamped:.3?}");
    (damped[1], undamped[1])
}

/// The axis of [`drop_l4_period`]'s mode: in the xy-plane, ½ asin √0.8
/// from x, where the cubic harmonic x⁴ + y⁴ + z⁴ − 3/5 vanishes.
#[allow(dead_code)]
pub fn l4_axis() -> sph_core::glam::Vec3 {
    let phi = 0.5 * 0.8f32.sqrt().asin();
    sph_core::glam::Vec3::new(phi.cos(), phi.sin(), 0.0)
}

/// Rayleigh's l = 4 flow about [`l4_axis`] at y = x/R, ∇(|y|⁴ P₄(ŷ·n)/4):
/// divergence-free, its radial part P₄ on |y| = 1.
#[allow(dead_code)]
pub fn l4_flow(y: sph_core::glam::Vec3) -> sph_core::glam::Vec3 {
    let axis = l4_axis();
    let (z, r2) = (y.dot(axis), y.length_squared());
    ((140.0 * z * z * z - 60.0 * z * r2) * axis + (12.0 * r2 - 60.0 * z * z) * y) / 32.0
}

/// The l = 4 amplitude of positions `x` about centre `c` for a drop of
/// radius `r`: 3⟨r⁴ P₄(cos θ)⟩/R⁴ about [`l4_axis`], r⁴ P₄ as its harmonic
/// polynomial (35 z⁴ − 30 z² r² + 3 r⁴)/8. 0 for a lattice sphere, ε for
/// one moved by ε R [`l4_flow`].
#[allow(dead_code)]
pub fn l4_amplitude(x: &[sph_core::glam::Vec3], c: sph_core::glam::Vec3, r: f64) -> f64 {
    let axis = l4_axis().as_dvec3();
    let moment = (x.iter())
        .map(|x| {
            let d = (*x - c).as_dvec3();
            let (z, r2) = (d.dot(axis), d.length_squared());
            (35.0 * z.powi(4) - 30.0 * z * z * r2 + 3.0 * r2 * r2) / 8.0
        })
        .sum::<f64>()
        / x.len() as f64;
    3.0 * moment / r.powi(4)
}

/// The drops' surface tension (N/m): water's.
const SIGMA: f64 = 0.0728;

/// A weightless water drop (σ = 0.0728 N/m, μ = 0.01 Pa·s, h = 2
/// spacings): the lattice points x of a sphere of `across`³ cells' volume
/// and radius R, each moved to `shape(x, R)`, in a world of `solver`.
/// Returns it and the radius of the particles' volume.
#[allow(dead_code)]
fn drop_world(
    solver: sph_core::Solver,
    spacing: f32,
    across: u32,
    shape: impl Fn(sph_core::glam::Vec3, f32) -> sph_core::glam::Vec3,
) -> (sph_core::World, f64) {
    use sph_core::glam::Vec3;
    use sph_core::{Aabb, Boundary, FluidParams, Particles, TimeStepping, World};
    let params = FluidParams {
        gravity: Vec3::ZERO,
        surface_tension: SIGMA as f32,
        viscosity: 0.01,
        ..FluidParams::water(2.0 * spacing)
    };
    let mass = solver.particle_mass(&params, spacing).unwrap();
    let radius = (3.0 * (across as f32 * spacing).powi(3) / (4.0 * std::f32::consts::PI)).cbrt();
    let mut particles = Particles::new();
    let n = (radius / spacing).ceil() as i32 + 1;
    for k in -n..n {
        for j in -n..n {
            for i in -n..n {
                let x = (Vec3::new(i as f32, j as f32, k as f32) + 0.5) * spacing;
                if x.length() <= radius {
                    particles.push(shape(x, radius), Vec3::ZERO, mass);
                }
            }
        }
    }
    let count = particles.len();
    if across == 16 {
        assert_eq!(count, 4032);
    }
    let r = f64::from((3.0 * count as f32 * spacing.powi(3) / (4.0 * std::f32::consts::PI)).cbrt());
    let boundary = Boundary::new(Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0)));
    let world =
        World::with_solver(particles, params, boundary, TimeStepping::default(), solver).unwrap();
    (world, r)
}

/// The mechanical pressure (Pa) of the particles `which` of `p` under PBF
/// or DFSPH: (ρ_i/6) Σ_j (x_i − x_j)·a_ij over the solver's pressure forces
/// a_ij = −V_j (κ_i + κ_j) ∇W_ij, plus `akinci[i]`, the surface tension
/// forces' own virial. Under DFSPH κ is ρ0 p/ρ² and W the cubic spline (a
/// uniform pressure p reads 1.020 p on the filled lattice), under PBF
/// κ = p/ρ0 and ∇W spiky's, the pressure whose acceleration over Δt² is
/// PBF's correction (0.947 p). Meaningful in the bulk, where the pairs of
/// a particle sample the stress about it.
#[allow(dead_code)]
pub fn pair_virial_pressures(
    p: &sph_core::Particles,
    kind: sph_core::SolverKind,
    params: &sph_core::FluidParams,
    akinci: &[f32],
    which: &[usize],
) -> Vec<f64> {
    use sph_core::{CubicSpline, Kernel, NeighbourGrid, SolverKind, Spiky};
    let (rho0, h) = (params.rest_density, params.h);
    let (cubic, spiky) = (CubicSpline::new(h).unwrap(), Spiky::new(h).unwrap());
    let (x, m, rho, pr) = (p.positions(), p.masses(), p.densities(), p.pressures());
    let kappa = |i: usize| match kind {
        SolverKind::Pbf => pr[i] / rho0,
        _ => rho0 * pr[i] / (rho[i] * rho[i]),
    };
    let gradient = |d| match kind {
        SolverKind::Pbf => spiky.gradient(d),
        _ => cubic.gradient(d),
    };
    let grid = NeighbourGrid::build(x, h).unwrap();
    (which.iter())
        .map(|&i| {
            let mut w = 0.0f64;
            grid.for_each_neighbour(i, |j, _, _| {
                let d = x[i] - x[j];
                let a = -(m[j] / rho0) * (kappa(i) + kappa(j)) * gradient(d);
                w += f64::from(d.dot(a));
            });
            f64::from(rho[i]) / 6.0 * w + akinci.get(i).map_or(0.0, |&v| f64::from(v))
        })
        .collect()
}

/// The mean of [`pair_virial_pressures`] over the particles of `p` within
/// `within` of `c`: the drop's inner mechanical pressure.
#[allow(dead_code)]
pub fn inner_pair_virial(
    p: &sph_core::Particles,
    kind: sph_core::SolverKind,
    params: &sph_core::FluidParams,
    akinci: &[f32],
    c: sph_core::glam::Vec3,
    within: f64,
) -> f64 {
    let inside = indices_within(p, c, within);
    mean(&pair_virial_pressures(p, kind, params, akinci, &inside))
}

/// The particles of `p` within `within` of `c`.
fn indices_within(p: &sph_core::Particles, c: sph_core::glam::Vec3, within: f64) -> Vec<usize> {
    let x = p.positions();
    (0..x.len())
        .filter(|&i| f64::from((x[i] - c).length()) < within)
        .collect()
}

/// The mean of `values`; 0 for none.
fn mean(values: &[f64]) -> f64 {
    values.iter().sum::<f64>() / values.len().max(1) as f64
}

/// The kinetic part of the mechanical pressure (Pa) of the particles of
/// `p` within `within` of `c`: the mean of ρ_i |v_i − v̄|²/3, with v̄ the
/// mean velocity of all particles (the drop's centre of mass, for equal
/// masses). The virial theorem's other half: a fluid whose particles move
/// about their mean carries part of its pressure as that motion's momentum
/// flux, as a gas does, and its pair forces' virial reads that much less.
#[allow(dead_code)]
pub fn inner_kinetic_pressure(
    p: &sph_core::Particles,
    c: sph_core::glam::Vec3,
    within: f64,
) -> f64 {
    let (v, rho) = (p.velocities(), p.densities());
    let centre = v.iter().sum::<sph_core::glam::Vec3>() / v.len().max(1) as f32;
    let kinetic: Vec<f64> = (indices_within(p, c, within).into_iter())
        .map(|i| f64::from(rho[i]) * f64::from((v[i] - centre).length_squared()) / 3.0)
        .collect();
    mean(&kinetic)
}

/// A processor that reads `N` figures of the particles after every step
/// ending after `from` (s) and sums them weighted by the step, into
/// `sums` (the weighted sums, and the time they cover): the mean over
/// every step, not over frames. DFSPH splits a frame into steps of unequal
/// length, and its κ corrects each step's leftover compression in that
/// step, so its pressure pulses from step to step; a reading after each
/// frame's last, shorter step only is biased.
#[allow(dead_code)]
pub struct StepAverage<const N: usize, F> {
    pub read: F,
    pub from: f64,
    pub sums: std::sync::Arc<std::sync::Mutex<([f64; N], f64)>>,
}

impl<const N: usize, F> sph_core::Processor for StepAverage<N, F>
where
    F: FnMut(&sph_core::Particles) -> [f64; N] + Send,
{
    fn name(&self) -> &str {
        "step average"
    }
    fn process(
        &mut self,
        particles: &mut sph_core::Particles,
        ctx: &mut sph_core::Context,
    ) -> sph_core::Result<()> {
        let dt = f64::from(ctx.dt);
        if ctx.time + dt > self.from {
            let figures = (self.read)(particles);
            let mut sums = self.sums.lock().unwrap_or_else(|e| e.into_inner());
            for (sum, figure) in sums.0.iter_mut().zip(figures) {
                *sum += figure * dt;
            }
            sums.1 += dt;
        }
        Ok(())
    }
}

/// The means of a [`StepAverage`]'s sums so far (NaN before any step was
/// read).
#[allow(dead_code)]
pub fn step_means<const N: usize>(sums: &std::sync::Mutex<([f64; N], f64)>) -> [f64; N] {
    let (sums, time) = *sums.lock().unwrap_or_else(|e| e.into_inner());
    sums.map(|s| s / time)
}

/// A DFSPH drop of 4,032 particles at `spacing`, at rest on the lattice
/// from the start, run for `seconds` in 1/60 s frames: its mechanical
/// pressure within R/2 of the centre over Laplace's 2σ/R, the mean over
/// every step of the last second weighted by the step's length
/// ([`StepAverage`]: read after each frame only, this drop reads 0.909
/// where every step weighted reads 0.805). Read as the
/// virial of every pair force on those particles,
/// (ρ_i/6) Σ_j (x_i − x_j)·(a_ij^pressure + a_ij^Akinci), with
/// a_ij^pressure = −V_j (κ_i + κ_j) ∇W_ij, κ = ρ0 p/ρ² (the stored
/// pressure as DFSPH's κ) and W the cubic spline: a stored pressure
/// stands for the continuum's virial, which on the lattice the kernel's
/// sum misses by a few per cent of the bulk pressure, as large as the jump
/// (`solver::surface_tension`'s module docs).
#[allow(dead_code)]
pub fn dfsph_drop_laplace(spacing: f32, seconds: f64) -> f64 {
    use sph_core::Particles;
    use sph_core::glam::Vec3;
    use sph_core::processor::{Context, Processor};
    use sph_core::solver::surface_tension::{SurfaceTension, Update};
    use std::sync::{Arc, Mutex};

    /// The surface tension station, its virial per particle copied out
    /// after each step.
    struct Measured(SurfaceTension, Arc<Mutex<Vec<f32>>>);
    impl Processor for Measured {
        fn name(&self) -> &str {
            self.0.name()
        }
        fn process(&mut self, p: &mut Particles, ctx: &mut Context) -> sph_core::Result<()> {
            self.0.process(p, ctx)?;
            let mut virial = self.1.lock().unwrap();
            virial.clear();
            virial.extend(self.0.virial());
            Ok(())
        }
    }

    let solver = sph_core::Solver::Dfsph(sph_core::DfsphParams::default());
    let (mut world, r) = drop_world(solver, spacing, 16, |x, _| x);
    let params = *world.params();
    let virial = Arc::new(Mutex::new(Vec::new()));
    let station = SurfaceTension::new(&params, Update::Accelerations).unwrap();
    let program = world.program_mut();
    assert!(program.remove("surface tension"));
    assert!(program.insert_after("forces", Measured(station, virial.clone())));
    let sums = Arc::new(Mutex::new(([0.0], 0.0)));
    program.push(StepAverage {
        read: move |p: &Particles| {
            let x = p.positions();
            let c = x.iter().sum::<Vec3>() / x.len() as f32;
            let virial = virial.lock().unwrap();
            let kind = sph_core::SolverKind::Dfsph;
            [inner_pair_virial(p, kind, &params, &virial, c, 0.5 * r)]
        },
        from: seconds - 1.0 + 1e-9,
        sums: sums.clone(),
    });
    while world.time() < seconds - 1e-9 {
        world.advance(1.0 / 60.0).unwrap();
    }
    let [pressure] = step_means(&sums);
    pressure / (2.0 * SIGMA / r)
}

/// The drop of [`drop_world`] run by `solver` for `seconds` in 1/60 s
/// frames. Returns `signal` (positions, centre, R of the particles'
/// volume) at the start and after each frame, Rayleigh's period for mode
/// `l` and that R.
#[allow(dead_code)]
fn drop_oscillation(
    solver: sph_core::Solver,
    spacing: f32,
    across: u32,
    l: u32,
    shape: impl Fn(sph_core::glam::Vec3, f32) -> sph_core::glam::Vec3,
    signal: impl Fn(&[sph_core::glam::Vec3], sph_core::glam::Vec3, f64) -> f64,
    seconds: f64,
) -> (Vec<(f64, f64)>, f64, f64) {
    use sph_core::Particles;
    use sph_core::glam::Vec3;
    let (mut world, r) = drop_world(solver, spacing, across, shape);
    let l = f64::from(l);
    let omega2 = l * (l - 1.0) * (l + 2.0) * SIGMA / (1000.0 * r.powi(3));
    let rayleigh = 2.0 * std::f64::consts::PI / omega2.sqrt();
    let measure = |p: &Particles| {
        let c = p.positions().iter().sum::<Vec3>() / p.len() as f32;
        signal(p.positions(), c, r)
    };
    let mut series = vec![(0.0, measure(&world.particles))];
    while world.time() < seconds - 1e-9 {
        world.advance(1.0 / 60.0).unwrap();
        series.push((world.time(), measure(&world.particles)));
    }
    (series, rayleigh, r)
}

/// The angular frequency ω and decay rate β of the damped oscillation
/// c + e^(−βt) (a cos ωt + b sin ωt) that fits `series` (t, y) best in
/// least squares: ω searched from ½ to 2 × `omega`, in steps of 0.25 %, β
/// from 0 to 10/s in steps of 0.02/s, (a, b, c) solved for each. A swing
/// damped within two periods leaves two or three turns, whose spacing
/// moves by 10 % with the noise; the fit uses every sample. `None` where
/// no fit is finite or the best lies at an edge of the search (no
/// oscillation in that range).
#[allow(dead_code)]
pub fn damped_fit(series: &[(f64, f64)], omega: f64) -> Option<(f64, f64)> {
    // The search's range scales with ω: none to search without one.
    if !(omega.is_finite() && omega > 0.0) {
        return None;
    }
    let decay: Vec<Vec<f64>> = (0..=500)
        .map(|k| {
            series
                .iter()
                .map(|&(t, _)| (-0.02 * f64::from(k) * t).exp())
                .collect()
        })
        .collect();
    let mut best = (f64::INFINITY, omega, 0.0);
    let mut w = 0.5 * omega;
    while w <= 2.0 * omega {
        let (cos, sin): (Vec<f64>, Vec<f64>) = series
            .iter()
            .map(|&(t, _)| ((w * t).cos(), (w * t).sin()))
            .unzip();
        for (k, e) in decay.iter().enumerate() {
            let basis = |i: usize| [e[i] * cos[i], e[i] * sin[i], 1.0];
            // Normal equations for the basis (e cos, e sin, 1).
            let (mut m, mut v) = ([[0.0f64; 3]; 3], [0.0f64; 3]);
            for (i, &(_, y)) in series.iter().enumerate() {
                let f = basis(i);
                for r in 0..3 {
                    v[r] += f[r] * y;
                    for c in 0..3 {
                        m[r][c] += f[r] * f[c];
                    }
                }
            }
            let Some(x) = solve3(m, v) else { continue };
            let sse: f64 = (series.iter().enumerate())
                .map(|(i, &(_, y))| {
                    let f = basis(i);
                    (y - x[0] * f[0] - x[1] * f[1] - x[2]).powi(2)
                })
                .sum();
            if sse < best.0 {
                best = (sse, w, 0.02 * k as f64);
            }
        }
        w *= 1.0025;
    }
    let (sse, w, beta) = best;
    // A fit at an edge of the search (or none) found no oscillation.
    let inside = w > 0.5 * omega * 1.0025 && w < 2.0 * omega / 1.0025 && beta < 10.0;
    (sse.is_finite() && inside).then_some((w, beta))
}

/// The solution of the 3×3 system m x = v by Cramer's rule, or `None`
/// where m is singular.
fn solve3(m: [[f64; 3]; 3], v: [f64; 3]) -> Option<[f64; 3]> {
    let det = |a: [[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let d = det(m);
    if d.abs() < 1e-300 {
        return None;
    }
    Some([0, 1, 2].map(|c| {
        let mut a = m;
        for r in 0..3 {
            a[r][c] = v[r];
        }
        det(a) / d
    }))
}

#[allow(dead_code)]
/// An n × n × n lattice of particles of `mass`, `step` apart from `origin`,
/// at rest.
pub fn lattice(n: i32, step: f32, origin: sph_core::glam::Vec3, mass: f32) -> sph_core::Particles {
    let mut particles = sph_core::Particles::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let x = origin + sph_core::glam::Vec3::new(i as f32, j as f32, k as f32) * step;
                particles.push(x, sph_core::glam::Vec3::ZERO, mass);
            }
        }
    }
    particles
}

#[allow(dead_code)]
/// `particles` in a domain far larger than they reach (20 m across), run
/// by `solver`, with the fluid's surface tension off.
pub fn unbounded(
    particles: sph_core::Particles,
    params: sph_core::FluidParams,
    solver: sph_core::Solver,
) -> Result<sph_core::World, sph_core::Error> {
    use sph_core::glam::Vec3;
    let boundary =
        sph_core::Boundary::new(sph_core::Aabb::new(Vec3::splat(-10.0), Vec3::splat(10.0)));
    let params = sph_core::FluidParams {
        surface_tension: 0.0,
        ..params
    };
    let stepping = sph_core::TimeStepping::default();
    sph_core::World::with_solver(particles, params, boundary, stepping, solver)
}

/// A spreading current's radius about `centre` (horizontal, in x and z):
/// the median over 32 equal sectors of each sector's farthest particle
/// with at least 5 neighbours within `h`. A lone particle ahead of the
/// front does not count, and the median does not follow the one particle
/// of a hundred on the front that leads (the farthest over all particles
/// did: 3.5 % between two currents that agree within 1.4 % by this).
#[allow(dead_code)]
pub fn current_radius(
    positions: &[sph_core::glam::Vec3],
    centre: sph_core::glam::Vec3,
    h: f32,
) -> f32 {
    use std::f32::consts::{PI, TAU};
    const SECTORS: usize = 32;
    let grid = sph_core::NeighbourGrid::build(positions, h).unwrap();
    let lists = sph_core::NeighbourLists::build(&grid).unwrap();
    let mut far = [0.0f32; SECTORS];
    for i in (0..positions.len()).filter(|&i| lists.of(i).len() >= 5) {
        let d = positions[i] - centre;
        let sector = ((d.z.atan2(d.x) + PI) / TAU * SECTORS as f32) as usize;
        let far = &mut far[sector.min(SECTORS - 1)];
        *far = far.max(d.x.hypot(d.z));
    }
    far.sort_by(f32::total_cmp);
    0.5 * (far[SECTORS / 2 - 1] + far[SECTORS / 2])
}

/// Huppert (1982)'s axisymmetric viscous current (`tests/huppert.rs`): a
/// cylinder of radius 0.113 m (r0, the radius of a 0.2 m square's area)
/// and height 0.1 m let go on the floor of a 1.2 m square tank, DFSPH with
/// its implicit viscosity μ, the walls' clearance `clearance` (`None`: the
/// scene's default, half a spacing).
#[allow(dead_code)]
pub struct HuppertCurrent {
    pub world: sph_core::World,
    /// The particles' count.
    pub particles: usize,
    /// The cylinder's axis on the floor.
    pub centre: sph_core::glam::Vec3,
    /// The kernel radius (m), for [`current_radius`].
    pub h: f32,
    /// Huppert's late-time radius over t^{1/8}: 0.894 (ρ g V³ / 3μ)^{1/8}.
    pub k: f64,
}

#[allow(dead_code)]
impl HuppertCurrent {
    /// The current at `spacing` (m), `mu` (Pa·s) and `clearance` (m).
    pub fn new(spacing: f32, mu: f32, clearance: Option<f32>) -> sph_core::Result<Self> {
        let (height, tank) = (0.1f32, 1.2f32);
        let r0 = 0.2 / std::f32::consts::PI.sqrt();
        let mut scene = sph_core::Scene::dam_break(2.0 * r0, height, spacing)
            .with_solver(sph_core::SolverKind::Dfsph);
        scene.fluid.viscosity = Some(mu);
        scene.clearance = clearance;
        scene.domain.max = [tank, 0.3, tank];
        let c = 0.5 * tank;
        scene.blocks[0].min = [c - r0, 0.0, c - r0];
        scene.blocks[0].max = [c + r0, height, c + r0];
        // A block 2 r0 square cut to the cylinder of radius r0: Huppert's
        // current is axisymmetric, and a square's corners would lead it
        // for seconds. (Cut from a block 0.2 m square instead, as
        // `tests/huppert.rs` once was, the "cylinder" kept the square's
        // flat sides: 3,600 particles at 1 cm.)
        let mut particles = scene.particles()?;
        let keep: Vec<bool> = (particles.positions().iter())
            .map(|x| (x.x - c).hypot(x.z - c) <= r0)
            .collect();
        particles.retain(&keep)?;
        let count = particles.len();
        let volume = count as f64 * f64::from(spacing).powi(3);
        let rho_g = f64::from(scene.fluid.rest_density) * 9.81;
        Ok(Self {
            world: scene.world_with(particles)?,
            particles: count,
            centre: sph_core::glam::Vec3::new(c, 0.0, c),
            h: scene.fluid.h,
            k: 0.894 * (rho_g * volume.powi(3) / (3.0 * f64::from(mu))).powf(0.125),
        })
    }

    /// Advances to `t` (s) in frames of at most 1/60 s, handing each
    /// frame's report to `report`; returns the radius ([`current_radius`])
    /// and Huppert's, k t^{1/8} (m).
    pub fn run_to(
        &mut self,
        t: f64,
        mut report: impl FnMut(&sph_core::FrameReport),
    ) -> sph_core::Result<(f64, f64)> {
        while self.world.time() < t - 1e-9 {
            let frame = ((t - self.world.time()) as f32).min(1.0 / 60.0);
            report(&self.world.advance(frame)?);
        }
        let r = current_radius(self.world.particles.positions(), self.centre, self.h);
        Ok((f64::from(r), self.k * t.powf(0.125)))
    }
}

/// Over samples (t, r, Huppert's r) of a [`HuppertCurrent`]: the exponent
/// of log r against log t (Huppert's is 1/8) and the rate r⁸ grows at
/// over Huppert's k⁸, the similarity solution's whatever its virtual time
/// origin.
#[allow(dead_code)]
pub fn huppert_fit(samples: &[(f64, f64, f64)]) -> (f64, f64) {
    let exponent = slope(samples.iter().map(|&(t, r, _)| (t.ln(), r.ln())));
    let k8 = samples[0].2.powi(8) / samples[0].0;
    let rate = slope(samples.iter().map(|&(t, r, _)| (t, r.powi(8)))) / k8;
    (exponent, rate)
}
