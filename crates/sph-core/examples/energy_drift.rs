//! Energy bookkeeping of a closed tank of water at rest, for both pressure kernels.
//!
//! `cargo run --release -p sph-core --example energy_drift`
//!
//! A 0.4 m cube of water (8,000 particles, k = 500, μ = 1) is released in a tank
//! and run for 1.5 s. Nothing drives it, so its total energy per unit mass —
//! kinetic + gravitational + the pressure energy Σ m u(ρ) of the equation of
//! state, u(ρ) = k (ln(ρ/ρ0) + ρ0/ρ − 1) for ρ > ρ0 (0 below, where p is
//! clamped) — may only fall (viscosity, inelastic walls). A rise is energy the
//! discretisation creates.

use sph_core::scene::WcsphSpec;
use sph_core::{PressureKernel, Result, Scene};

fn main() -> Result<()> {
    for kernel in [PressureKernel::Poly6, PressureKernel::Spiky] {
        let w = 0.4f32;
        let mut scene = Scene::dam_break(w, w, 0.02);
        scene.domain.max = [w, 0.6, w];
        scene.blocks[0].max = [w, 0.4, w];
        scene.solver.wcsph = Some(WcsphSpec {
            stiffness: 500.0,
            pressure_kernel: kernel,
            ..WcsphSpec::default()
        });
        scene.fluid.viscosity = Some(1.0);
        let (k, rho0, g) = (500.0f64, scene.fluid.rest_density as f64, 9.81f64);
        let mut world = scene.build_world()?;
        println!("{kernel:?}: time (s), energy (J/kg), kinetic (J/kg), mean density (kg/m³)");
        let mut next = 0.0;
        while world.time() < 1.5 {
            world.step()?;
            if world.time() >= next {
                let p = &world.particles;
                let n = p.len() as f64;
                let (mut kin, mut pot, mut int, mut rho) = (0.0, 0.0, 0.0, 0.0);
                for i in 0..p.len() {
                    kin += 0.5 * p.velocities()[i].length_squared() as f64;
                    pot += g * p.positions()[i].y as f64;
                    let r = p.densities()[i] as f64 / rho0;
                    int += if r > 1.0 {
                        k * (r.ln() + 1.0 / r - 1.0)
                    } else {
                        0.0
                    };
                    rho += p.densities()[i] as f64;
                }
                println!(
                    "{:5.2} {:8.4} {:8.4} {:7.1}",
                    world.time(),
                    (kin + pot + int) / n,
                    kin / n,
                    rho / n
                );
                next += 0.25;
            }
        }
    }
    Ok(())
}
