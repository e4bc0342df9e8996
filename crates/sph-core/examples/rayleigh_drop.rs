//! A free drop in zero gravity, pulled round by surface tension, against
//! Rayleigh (1879): a drop of radius R disturbed in its mode l oscillates at
//! ω² = l(l − 1)(l + 2) σ / (ρ R³), damped at Lamb's rate (l − 1)(2l + 1) ν / R².
//! The drop starts as a box elongated 2:1:1 along x (mostly l = 2) of the
//! volume of a sphere of radius R (4,225 particles at 5 mm, water's σ,
//! μ = 0.01 Pa·s), at rest; printed for the solver given (WCSPH by
//! default; STIFFNESS is WCSPH's k, water's 200 m²/s² by default): the
//! extent along x against time (2√5 times the rms offset along x: 2R for a
//! sphere, 1.61 × 2R at the start), the particles escaped beyond 3R, the
//! period from the extent's extrema, Rayleigh's, and their ratio. For
//! issue 42 (surface tension in every solver): today only WCSPH applies σ.
//!
//! ```text
//! cargo run --release -p sph-core --example rayleigh_drop [-- SOLVER [SECONDS [STIFFNESS]]]
//! ```

use sph_core::glam::Vec3;
use sph_core::{Aabb, Boundary, FluidParams, Particles, Solver, SolverKind, TimeStepping, World};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let kind = match args.next() {
        Some(name) => SolverKind::from_name(&name).ok_or(format!("unknown solver `{name}`"))?,
        None => SolverKind::Wcsph,
    };
    let seconds: f64 = args.next().map_or(Ok(4.0), |s| s.parse())?;
    let water = FluidParams::water(0.01);
    let stiffness: f32 = args.next().map_or(Ok(water.stiffness), |s| s.parse())?;
    // The issue's drop: 4,096 particles at 5 mm, water's σ and a viscosity
    // low enough that the oscillation outlives a few periods.
    let (spacing, sigma, mu) = (0.005f32, 0.0728f32, 0.01f32);
    let params = FluidParams {
        gravity: Vec3::ZERO,
        surface_tension: sigma,
        viscosity: mu,
        stiffness,
        ..FluidParams::water(2.0 * spacing)
    };
    let solver = match kind {
        SolverKind::Wcsph => Solver::Wcsph,
        SolverKind::Pbf => Solver::Pbf(Default::default()),
        SolverKind::Dfsph => Solver::Dfsph(Default::default()),
    };
    let mass = solver.particle_mass(&params, spacing)?;
    // A box (2b, b, b) of the volume of 16 × 16 × 16 particles: 4/3 π R³.
    let n = 16.0f32;
    let volume = (n * spacing).powi(3);
    let b = (volume / 2.0).cbrt();
    let (nx, ny) = (
        (2.0 * b / spacing).round() as i32,
        (b / spacing).round() as i32,
    );
    let mut particles = Particles::new();
    for k in 0..ny {
        for j in 0..ny {
            for i in 0..nx {
                let x = (Vec3::new(i as f32, j as f32, k as f32) + 0.5) * spacing
                    - 0.5 * Vec3::new(nx as f32, ny as f32, ny as f32) * spacing;
                particles.push(x, Vec3::ZERO, mass);
            }
        }
    }
    let count = particles.len();
    let radius =
        (3.0 * count as f64 * f64::from(spacing).powi(3) / (4.0 * std::f64::consts::PI)).cbrt();
    let rho = f64::from(params.rest_density);
    let (l, nu) = (2.0f64, f64::from(mu) / rho);
    let omega = (l * (l - 1.0) * (l + 2.0) * f64::from(sigma) / (rho * radius.powi(3))).sqrt();
    let rayleigh = 2.0 * std::f64::consts::PI / omega;
    let lamb = (l - 1.0) * (2.0 * l + 1.0) * nu / (radius * radius);
    let boundary = Boundary::new(Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0)));
    let mut world =
        World::with_solver(particles, params, boundary, TimeStepping::default(), solver)?;
    println!(
        "{kind}: {count} particles, R = {radius:.4} m, σ = {sigma} N/m, μ = {mu} Pa·s; \
         k = {stiffness} m²/s²; Rayleigh's l = 2 period {rayleigh:.3} s, Lamb's damping {lamb:.3} 1/s"
    );
    // The extent along x: twice the rms distance from the centre along x
    // over √(1/5), the ratio of a sphere's, so a sphere reads 2R; and the
    // particles more than 3R from the centre (escaped spray).
    let extent = |p: &Particles| {
        let c = p.positions().iter().sum::<Vec3>() / p.len() as f32;
        let var = p
            .positions()
            .iter()
            .map(|x| f64::from((x.x - c.x).powi(2)))
            .sum::<f64>()
            / p.len() as f64;
        let far = (p.positions().iter())
            .filter(|x| f64::from((**x - c).length()) > 3.0 * radius)
            .count();
        (2.0 * (5.0 * var).sqrt(), far)
    };
    let frame = 1.0 / 60.0;
    let mut series = vec![(0.0f64, extent(&world.particles).0)];
    let mut escaped = vec![0];
    while world.time() < seconds - 1e-9 {
        world.advance(frame)?;
        let (e, far) = extent(&world.particles);
        series.push((world.time(), e));
        escaped.push(far);
    }
    // Extrema of the extent (local maxima and minima), each a half period apart.
    let mut extrema = Vec::new();
    for w in series.windows(3) {
        let (a, b, c) = (w[0].1, w[1].1, w[2].1);
        if (b > a && b >= c) || (b < a && b <= c) {
            extrema.push(w[1]);
        }
    }
    for ((t, e), far) in series.iter().zip(&escaped).step_by(6) {
        println!(
            "  t = {t:5.2} s  extent along x {e:.4} m ({:.3} of 2R), {far} particles beyond 3R",
            e / (2.0 * radius)
        );
    }
    println!("extrema (t, extent): {extrema:.3?}");
    if extrema.len() >= 3 {
        let half: Vec<f64> = extrema.windows(2).map(|w| w[1].0 - w[0].0).collect();
        let period = 2.0 * half.iter().sum::<f64>() / half.len() as f64;
        println!(
            "period {period:.3} s from {} half periods; Rayleigh {rayleigh:.3} s; ratio {:.2} \
             (frequency {:.2} of Rayleigh's)",
            half.len(),
            period / rayleigh,
            rayleigh / period
        );
    } else {
        println!("fewer than three extrema in {seconds} s: no period to measure");
    }
    Ok(())
}
