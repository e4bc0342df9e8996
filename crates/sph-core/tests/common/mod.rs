//! Helpers shared by the solver tests. Each test crate compiles this
//! module and uses part of it.

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

/// The l = 2 period of a weightless water drop (σ = 0.0728 N/m, μ = 0.01
/// Pa·s, h = 2 spacings) of 4,032 particles (a sphere of the volume of 16³
/// lattice cells, R ≈ 9.9 spacings) stretched by
/// `stretch` along x, run by `solver` for `seconds`, over Rayleigh's: the
/// mean spacing of the extent's turns (2√5 × the rms offset along x, 2R
/// for a sphere; a turn at least 1 % of 2R from the last).
#[allow(dead_code)]
pub fn drop_period(solver: sph_core::Solver, spacing: f32, stretch: f32, seconds: f64) -> f64 {
    use sph_core::glam::Vec3;
    use sph_core::{Aabb, Boundary, FluidParams, Particles, TimeStepping, World};
    let params = FluidParams {
        gravity: Vec3::ZERO,
        surface_tension: 0.0728,
        viscosity: 0.01,
        ..FluidParams::water(2.0 * spacing)
    };
    let mass = solver.particle_mass(&params, spacing).unwrap();
    let radius = (3.0 * (16.0 * spacing).powi(3) / (4.0 * std::f32::consts::PI)).cbrt();
    let scale = Vec3::new(stretch, stretch.powf(-0.5), stretch.powf(-0.5));
    let mut particles = Particles::new();
    let n = (radius / spacing).ceil() as i32 + 1;
    for k in -n..n {
        for j in -n..n {
            for i in -n..n {
                let x = (Vec3::new(i as f32, j as f32, k as f32) + 0.5) * spacing;
                if x.length() <= radius {
                    particles.push(x * scale, Vec3::ZERO, mass);
                }
            }
        }
    }
    assert_eq!(particles.len(), 4032);
    let r = f64::from((3.0 * 4032.0 * spacing.powi(3) / (4.0 * std::f32::consts::PI)).cbrt());
    let rayleigh = 2.0 * std::f64::consts::PI / (8.0 * 0.0728 / (1000.0 * r.powi(3))).sqrt();
    let boundary = Boundary::new(Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0)));
    let mut world =
        World::with_solver(particles, params, boundary, TimeStepping::default(), solver).unwrap();
    // The extent along x (2√5 × the rms offset: 2R for a sphere) per frame,
    // and its turns at least 1 % of 2R from the last.
    let extent = |p: &Particles| {
        let c = p.positions().iter().sum::<Vec3>() / p.len() as f32;
        let var = (p.positions().iter())
            .map(|x| f64::from((x.x - c.x).powi(2)))
            .sum::<f64>()
            / p.len() as f64;
        2.0 * (5.0 * var).sqrt()
    };
    let mut series = vec![(0.0, extent(&world.particles))];
    while world.time() < seconds - 1e-9 {
        world.advance(1.0 / 60.0).unwrap();
        series.push((world.time(), extent(&world.particles)));
    }
    let (mut turns, mut last) = (Vec::new(), series[0].1);
    for w in series.windows(3) {
        let (a, b, c) = (w[0].1, w[1].1, w[2].1);
        if ((b > a && b >= c) || (b < a && b <= c)) && (b - last).abs() > 0.02 * r {
            turns.push(w[1].0);
            last = b;
        }
    }
    assert!(turns.len() >= 3, "stretch {stretch}: turns at {turns:?}");
    2.0 * (turns[turns.len() - 1] - turns[0]) / (turns.len() - 1) as f64 / rayleigh
}
