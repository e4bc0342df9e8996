//! Extending the solver: a user processor with its own per-particle attribute.
//!
//! `cargo run --release -p sph-core --example custom_processor`
//!
//! A "temperature" attribute starts hot in the dam-break column and diffuses
//! between neighbours (an SPH laplacian, gathered like the solver's own forces);
//! a second processor adds buoyancy from it (Boussinesq: a = −β (T − T₀) g).
//! The same two processors run in both solvers' programs: the diffusion
//! after the `grid` station, the buoyancy after the `forces` station (both
//! programs have them: WCSPH computes its forces there, PBF sets gravity
//! before it predicts positions).

use sph_core::glam::Vec3;
use sph_core::processor::{Context, Processor};
use sph_core::{Kernels, Particles, Result, Scene, SolverKind};

/// Heat diffusion: dT_i/dt = α Σ_j m_j/ρ0 (T_j − T_i) ∇²W_visc(r_ij), with
/// the rest volumes m_j/ρ0 (right after the grid the step's densities are
/// not summed yet).
struct Diffuse {
    alpha: f32,
    rest_density: f32,
    kernels: Kernels,
}

impl Processor for Diffuse {
    fn name(&self) -> &str {
        "diffuse-heat"
    }

    fn process(&mut self, particles: &mut Particles, ctx: &mut Context) -> Result<()> {
        let grid = ctx.grid.as_ref().ok_or(sph_core::Error::Pipeline {
            processor: "diffuse-heat",
            reason: "needs the neighbour grid: insert it after `grid`",
        })?;
        let t = particles.attribute::<f32>("temperature")?;
        let (m, rho0) = (particles.masses(), self.rest_density);
        let visc = self.kernels.viscosity;
        let rate = grid.par_map(|i, nb| {
            let mut s = 0.0f32;
            nb.for_each(|j, _, r2| {
                s += m[j] / rho0 * (t[j] - t[i]) * visc.laplacian_len(r2.sqrt())
            });
            self.alpha * s
        });
        let dt = ctx.dt;
        for (t, r) in particles
            .attribute_mut::<f32>("temperature")?
            .iter_mut()
            .zip(rate)
        {
            *t += r * dt;
        }
        Ok(())
    }
}

/// Boussinesq buoyancy: warmer fluid is lighter by β (T − T₀) of its weight.
struct Buoyancy {
    /// Thermal expansion coefficient β (1/K).
    beta: f32,
    /// Reference temperature T₀ (°C).
    reference: f32,
    gravity: Vec3,
}

impl Processor for Buoyancy {
    fn name(&self) -> &str {
        "buoyancy"
    }

    fn process(&mut self, particles: &mut Particles, _: &mut Context) -> Result<()> {
        // A copy, so that the accelerations can be borrowed mutably beside it.
        let t = particles.attribute::<f32>("temperature")?.to_vec();
        for (a, t) in particles.accelerations_mut().iter_mut().zip(t) {
            *a -= self.beta * (t - self.reference) * self.gravity;
        }
        Ok(())
    }
}

fn main() -> Result<()> {
    for kind in SolverKind::ALL {
        run(kind)?;
    }
    Ok(())
}

fn run(kind: SolverKind) -> Result<()> {
    let scene = Scene::dam_break(0.2, 0.06, 0.02).with_solver(kind);
    let mut world = scene.build_world()?;
    world.particles.add_attribute("temperature", 20.0f32)?;
    // The upper half of the column starts hot.
    let hot: Vec<bool> = world
        .particles
        .positions()
        .iter()
        .map(|x| x.y > 0.2)
        .collect();
    for (t, hot) in world
        .particles
        .attribute_mut::<f32>("temperature")?
        .iter_mut()
        .zip(hot)
    {
        if hot {
            *t = 80.0;
        }
    }
    let (h, rest_density) = (world.params().h, world.params().rest_density);
    world.program_mut().insert_after(
        "grid",
        Diffuse {
            alpha: 1e-3,
            rest_density,
            kernels: Kernels::new(h)?,
        },
    );
    // β ten times water's (2.1e-4 /K), so that the effect shows in a second.
    let gravity = world.params().gravity;
    world.program_mut().insert_after(
        "forces",
        Buoyancy {
            beta: 2e-3,
            reference: 20.0,
            gravity,
        },
    );
    println!(
        "{kind}: {:?}",
        world.program_mut().names().collect::<Vec<_>>()
    );
    for frame in 0..30 {
        let report = world.advance(scene.time_step.frame_dt)?;
        if frame % 10 == 9 {
            let t = world.particles.attribute::<f32>("temperature")?;
            let (lo, hi) = t
                .iter()
                .fold((f32::MAX, f32::MIN), |(a, b), &x| (a.min(x), b.max(x)));
            println!(
                "t = {:.3} s ({} substeps this frame): temperature range {lo:.1} – {hi:.1} °C",
                report.time, report.substeps
            );
        }
    }
    Ok(())
}
