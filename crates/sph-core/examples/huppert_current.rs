//! `tests/huppert.rs`'s axisymmetric viscous current (a cylinder of radius
//! 0.113 m and height 0.1 m let go on a no-slip floor, DFSPH with its
//! implicit viscosity) at any spacing and wall clearance, against Huppert
//! (1982)'s late-time radius r(t) = 0.894 (ρ g V³ / 3μ)^{1/8} t^{1/8}: the
//! radius (`common::current_radius`) at √2 steps to `--seconds`, and over
//! the last three samples the exponent of log r against log t and the rate
//! r⁸ grows at against Huppert's. The test runs 1 cm; finer spacings tell
//! a resolution's artefact from the method's.
//!
//! ```text
//! cargo run --release -p sph-core --example huppert_current -- \
//!     [--spacing 0.01] [--clearance 0] [--mu 100] [--seconds 8]
//! ```

#[path = "../tests/common/mod.rs"]
mod common;

use sph_core::glam::Vec3;
use sph_core::{Scene, SolverKind};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (mut spacing, mut clearance, mut mu, mut seconds) = (0.01f32, 0.0f32, 100.0f32, 8.0f64);
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = || args.next().ok_or(format!("{arg} needs a value"));
        match arg.as_str() {
            "--spacing" => spacing = value()?.parse()?,
            "--clearance" => clearance = value()?.parse()?,
            "--mu" => mu = value()?.parse()?,
            "--seconds" => seconds = value()?.parse()?,
            other => return Err(format!("unknown argument `{other}`").into()),
        }
    }
    let (r0, height, tank) = (0.2f32 / std::f32::consts::PI.sqrt(), 0.1f32, 1.2f32);
    let mut scene = Scene::dam_break(2.0 * r0, height, spacing).with_solver(SolverKind::Dfsph);
    scene.fluid.viscosity = Some(mu);
    scene.clearance = clearance;
    scene.domain.max = [tank, 0.3, tank];
    let c = 0.5 * tank;
    // A block 2 r0 square, cut to the cylinder of radius r0.
    scene.blocks[0].min = [c - r0, 0.0, c - r0];
    scene.blocks[0].max = [c + r0, height, c + r0];
    let mut particles = scene.particles()?;
    let keep: Vec<bool> = (particles.positions().iter())
        .map(|x| (x.x - c).hypot(x.z - c) <= r0)
        .collect();
    particles.retain(&keep)?;
    let count = particles.len();
    let volume = count as f64 * f64::from(spacing).powi(3);
    let mut world = scene.world_with(particles)?;
    let rho_g = f64::from(scene.fluid.rest_density) * 9.81;
    let k = 0.894 * (rho_g * volume.powi(3) / (3.0 * f64::from(mu))).powf(0.125);
    let centre = Vec3::new(c, 0.0, c);
    println!(
        "{count} particles at {spacing} m, clearance {clearance} m, μ = {mu} Pa·s; t (s), r (m), Huppert (m)"
    );
    // √2 steps down from `seconds` to 0.2 s, in order.
    let mut times: Vec<f64> = (0..)
        .map(|k| seconds / 2f64.sqrt().powi(k))
        .take_while(|&t| t >= 0.2 - 1e-9)
        .collect();
    times.reverse();
    let mut rows = Vec::new();
    let start = std::time::Instant::now();
    for &t in &times {
        while world.time() < t - 1e-9 {
            world.advance(((t - world.time()) as f32).min(1.0 / 60.0))?;
        }
        let r = f64::from(common::current_radius(
            world.particles.positions(),
            centre,
            scene.fluid.h,
        ));
        let theory = k * t.powf(0.125);
        println!(
            "  {t:5.2} {r:.4} {theory:.4} ({:+.1} %)  [{:.0} s wall]",
            100.0 * (r / theory - 1.0),
            start.elapsed().as_secs_f64()
        );
        rows.push((t, r, theory));
    }
    if rows.len() >= 3 {
        let tail = &rows[rows.len() - 3..];
        let exponent = common::slope(tail.iter().map(|&(t, r, _)| (t.ln(), r.ln())));
        let k8 = tail[0].2.powi(8) / tail[0].0;
        let rate = common::slope(tail.iter().map(|&(t, r, _)| (t, r.powi(8)))) / k8;
        println!(
            "last three samples: exponent {exponent:.4} (Huppert 0.125); r⁸ grows at {rate:.3} of Huppert's rate"
        );
    }
    Ok(())
}
