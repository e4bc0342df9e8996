//! DFSPH's implicit viscosity (Weiler et al. 2018) against theory: a slug
//! driven by gravity down a square duct with no-slip walls reaches the
//! duct's Poiseuille profile; a fluid of 1,000 Pa·s runs at the flow's step,
//! far above the explicit viscous limit.

use sph_core::glam::Vec3;
use sph_core::{DfsphParams, PbfParams, PbfViscosity, Scene, SolverKind};

/// Steady laminar flow down a duct −a < y < a, −a < z < a under the body
/// force g per unit mass along x, no slip on the walls (White, Viscous
/// Fluid Flow, eq. 3-48): u = 16 a² g / (ν π³) Σ_{n odd} (−1)^((n−1)/2) / n³
/// [1 − cosh(nπz/2a) / cosh(nπ/2)] cos(nπy/2a).
fn duct(y: f64, z: f64, a: f64, g: f64, nu: f64) -> f64 {
    let mut sum = 0.0;
    for k in 0..40 {
        let n = (2 * k + 1) as f64;
        let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
        let c = n * std::f64::consts::PI / (2.0 * a);
        let ratio = (c * z).cosh() / (c * a).cosh();
        sum += sign / n.powi(3) * (1.0 - ratio) * (c * y).cos();
    }
    16.0 * a * a * g / (nu * std::f64::consts::PI.powi(3)) * sum
}

/// What a duct run measured: the middle third's mean |u − u_theory| over
/// the centre's speed, and its flow rate over theory's.
struct Duct {
    error: f64,
    flow: f64,
}

/// A slug 0.3 m long filling a 0.1 m square duct (3,000 particles at 1 cm,
/// h = 2 cm), μ = 100 Pa·s, gravity along the duct, run by `kind` for 0.3 s
/// (60 times the viscous time a²/ν); then the middle third's velocities
/// against the duct's profile at each particle's place.
fn duct_flow(kind: SolverKind) -> Duct {
    let (side, length, spacing, mu, g) = (0.1f32, 0.3f32, 0.01f32, 100.0f32, 9.81f32);
    let mut scene = Scene::dam_break(length, side, spacing).with_solver(kind);
    scene.fluid.h = 2.0 * spacing;
    scene.fluid.viscosity = Some(mu);
    scene.fluid.gravity = [g, 0.0, 0.0];
    scene.domain.min = [0.0, 0.0, 0.0];
    scene.domain.max = [1.0, side, side];
    scene.blocks[0].min = [0.05, 0.0, 0.0];
    scene.blocks[0].max = [0.05 + length, side, side];
    scene.solver.dfsph = Some(DfsphParams::default());
    scene.solver.pbf = Some(PbfParams {
        viscosity: PbfViscosity::Implicit,
        ..PbfParams::default()
    });
    let mut world = scene.build_world().unwrap();
    let n = world.particles.len();
    let mut viscosity_iterations = 0;
    let mut steps = 0;
    for _ in 0..18 {
        let r = world.advance(1.0 / 60.0).unwrap();
        viscosity_iterations += r.viscosity_iterations;
        steps += r.substeps;
        assert_eq!(r.unconverged, 0, "{kind:?}");
    }
    let p = &world.particles;
    let (a, nu) = (
        f64::from(side) / 2.0,
        f64::from(mu / scene.fluid.rest_density),
    );
    let centre = duct(0.0, 0.0, a, f64::from(g), nu);
    let xs: Vec<f32> = p.positions().iter().map(|x| x.x).collect();
    let (lo, hi) = (
        xs.iter().copied().fold(f32::MAX, f32::min),
        xs.iter().copied().fold(f32::MIN, f32::max),
    );
    let third = (hi - lo) / 3.0;
    let (mut error, mut flow, mut flow_exact, mut count) = (0.0f64, 0.0f64, 0.0f64, 0);
    for (x, v) in p.positions().iter().zip(p.velocities()) {
        if x.x < lo + third || x.x > hi - third {
            continue;
        }
        let exact = duct(f64::from(x.y) - a, f64::from(x.z) - a, a, f64::from(g), nu);
        error += (f64::from(v.x) - exact).abs();
        flow += f64::from(v.x);
        flow_exact += exact;
        count += 1;
    }
    let error = error / count as f64 / centre;
    let flow = flow / flow_exact;
    let transverse = (p.velocities().iter())
        .map(|v| Vec3::new(0.0, v.y, v.z).length())
        .fold(0.0f32, f32::max);
    println!(
        "{kind:?}: {n} particles, {steps} steps, {:.1} CG iterations per step; centre speed (theory) {centre:.4} m/s; \
         middle third ({count} particles): mean |u − u_theory| {:.2} % of it, flow rate {:.3} of theory; \
         largest transverse speed {transverse:.4} m/s",
        f64::from(viscosity_iterations) / f64::from(steps),
        100.0 * error,
        flow
    );
    assert_eq!(world.particles.len(), n);
    Duct { error, flow }
}

/// DFSPH: the mean error is at most 5 % of the centre's speed, and the
/// flow rate within 5 % (measured 4.7 % and −4.1 %; with the continuum's
/// laplacian factor 10 instead of the lattice's, 20 % and +41 %: the fluid
/// flowed as if 0.7 μ).
#[test]
fn gravity_driven_duct_flow_is_poiseuille() {
    let Duct { error, flow } = duct_flow(SolverKind::Dfsph);
    assert!(error <= 0.05, "mean error {error} of the centre speed");
    assert!((flow - 1.0).abs() <= 0.05, "flow rate {flow} of theory");
}

/// PBF with the implicit viscosity (`viscosity = "implicit"`) after its
/// velocity update, at its own substeps (3 per 60 Hz frame): the same
/// bounds as DFSPH's.
#[test]
fn pbf_duct_flow_is_poiseuille() {
    let Duct { error, flow } = duct_flow(SolverKind::Pbf);
    assert!(error <= 0.05, "mean error {error} of the centre speed");
    assert!((flow - 1.0).abs() <= 0.05, "flow rate {flow} of theory");
}

/// What a second of the slab dam break did at some μ.
#[derive(Debug)]
struct Slump {
    /// The shortest step (s) and the explicit viscous limit's.
    shortest: f32,
    explicit: f32,
    front: f32,
    /// The fastest particle at any frame's end (m/s).
    fastest: f32,
    /// The same while the front was more than h from the far wall (m/s):
    /// the run-out before its impact throws spray.
    fastest_running_out: f32,
    worst_average_error: f32,
    /// The fewest CG iterations per step in a frame.
    fewest_per_step: f32,
}

/// The demo's slab dam break (1,200 particles) at viscosity `mu` (Pa·s) for
/// one second of 60 Hz frames under `kind` (PBF with the implicit
/// viscosity): every solve converges and every particle stays in the tank.
fn slump(kind: SolverKind, mu: f32) -> Slump {
    let mut scene = Scene::dam_break(0.25, 0.08, 0.02).with_solver(kind);
    scene.fluid.viscosity = Some(mu);
    scene.solver.pbf = Some(PbfParams {
        viscosity: PbfViscosity::Implicit,
        ..scene.pbf_params()
    });
    let mut world = scene.build_world().unwrap();
    let explicit = world.params().viscous_dt();
    let mut shortest = f32::INFINITY;
    let mut worst_average_error = 0.0f32;
    let (mut fastest, mut fastest_running_out) = (0.0f32, 0.0f32);
    let (far_wall, mut reached) = (scene.domain.max[0] - scene.fluid.h, false);
    let mut fewest_per_step = f32::INFINITY;
    for _ in 0..60 {
        let r = world.advance(1.0 / 60.0).unwrap();
        shortest = shortest.min(r.dt_range.0.min(r.dt_range.1));
        fewest_per_step = fewest_per_step.min(r.viscosity_iterations as f32 / r.substeps as f32);
        let p = &world.particles;
        let speed = (p.velocities().iter()).fold(0.0f32, |f, v| f.max(v.length()));
        fastest = fastest.max(speed);
        reached |= p.positions().iter().any(|x| x.x >= far_wall);
        if !reached {
            fastest_running_out = fastest_running_out.max(speed);
        }
        worst_average_error = worst_average_error.max(r.density_error_avg);
        assert_eq!(r.unconverged, 0, "{kind:?}, μ {mu}: {r:?}");
    }
    let p = &world.particles;
    assert!(p.positions().iter().all(|&x| scene.boundary().admits(x)));
    let slump = Slump {
        shortest,
        explicit,
        front: p.positions().iter().map(|x| x.x).fold(f32::MIN, f32::max),
        fastest,
        fastest_running_out,
        worst_average_error,
        fewest_per_step,
    };
    println!("{kind:?}, μ = {mu} Pa·s: {slump:?}");
    slump
}

/// μ = 1,000 Pa·s (a thick honey: 10⁶ × water) in the demo's slab dam break:
/// the explicit viscous limit 0.125 h² ρ0/μ would be 0.2 ms; the implicit
/// solve runs at the solvers' own steps (DFSPH's max_dt, 5 ms, as the column
/// barely moves; PBF's substeps), stays finite and contained, and the
/// column only slumps.
#[test]
fn a_thousand_pascal_seconds_runs_at_the_flow_step() {
    for (kind, density_error) in [(SolverKind::Dfsph, 0.001), (SolverKind::Pbf, 0.01)] {
        let s = slump(kind, 1000.0);
        assert!(s.shortest >= 10.0 * s.explicit, "{kind:?}: {s:?}");
        assert!(s.worst_average_error <= density_error, "{kind:?}: {s:?}");
        // A fall through the column's height would reach √(2 g 0.5) ≈ 3 m/s.
        assert!(s.fastest < 0.3, "{kind:?}: {s:?}");
        assert!(s.front < 0.5, "{kind:?}: {s:?}");
        // The implicit solve, not the pressure solve, held it: every frame
        // took at least one CG iteration per step.
        assert!(s.fewest_per_step >= 1.0, "{kind:?}: {s:?}");
    }
}

/// Water's 1e-3 Pa·s under the same solve: the dam break runs out along
/// the floor (the front passes 0.6 m in a second, as Martin & Moyce's
/// surge does) with every CG solve converged, and until the front first
/// reaches the far wall its fastest particle runs at 0.6 to 1 times
/// Ritter's dry-bed front 2√(gH) = 4.4 m/s for the 0.5 m column (measured
/// 3.35 m/s for DFSPH, 3.26 for PBF; the impact's spray then reaches 5.6
/// and 4.2 m/s). The
/// solves take no CG iterations here: water's ν Δt/h² ≈ 3·10⁻⁷ leaves the
/// velocities within the solve's tolerance of its solution before the
/// first iteration.
#[test]
fn water_runs_under_the_implicit_solve() {
    let ritter = 2.0 * (9.81f32 * 0.5).sqrt();
    for kind in [SolverKind::Dfsph, SolverKind::Pbf] {
        let s = slump(kind, 1e-3);
        assert!(s.front > 0.6, "{kind:?}: {s:?}");
        assert!(
            (0.6 * ritter..ritter).contains(&s.fastest_running_out),
            "{kind:?}: {s:?}"
        );
    }
}
