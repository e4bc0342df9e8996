//! Viscous spreading against Huppert (1982), "The propagation of
//! two-dimensional and axisymmetric viscous gravity currents over a rigid
//! horizontal surface", J. Fluid Mech. 121: a fixed volume V of viscous
//! fluid spreading on a no-slip floor under gravity at low Reynolds number
//! reaches the radius r(t) = 0.894 (ρ g V³ / 3μ)^{1/8} t^{1/8} at late
//! times. DFSPH with its implicit viscosity, two viscosities a factor 10
//! apart.
//!
//! ```text
//! cargo test --release -p sph-core --test huppert -- --nocapture
//! ```

use sph_core::glam::Vec3;
use sph_core::{NeighbourGrid, NeighbourLists, Scene, SolverKind};

/// The current's radius: the farthest horizontal distance from the centre
/// of the particles with at least 5 neighbours (a lone particle ahead of
/// the front does not count).
fn radius(positions: &[Vec3], centre: Vec3, h: f32) -> f32 {
    let grid = NeighbourGrid::build(positions, h).unwrap();
    let lists = NeighbourLists::build(&grid);
    (0..positions.len())
        .filter(|&i| lists.of(i).len() >= 5)
        .map(|i| {
            let d = positions[i] - centre;
            (d.x * d.x + d.z * d.z).sqrt()
        })
        .fold(0.0f32, f32::max)
}

/// A 0.2 × 0.1 × 0.2 m block (V = 0.004 m³, 4,000 particles at 1 cm) let
/// go on the floor of a 1.2 m square tank: (t, r, Huppert's r) at t = 1,
/// √2, 2, 2√2 and 4 s.
fn spread(mu: f32) -> Vec<(f64, f64, f64)> {
    let (side, height, tank, spacing) = (0.2f32, 0.1f32, 1.2f32, 0.01f32);
    let mut scene = Scene::dam_break(side, side, spacing).with_solver(SolverKind::Dfsph);
    scene.fluid.viscosity = mu;
    scene.domain.max = [tank, 0.3, tank];
    let c = 0.5 * tank;
    scene.blocks[0].min = [c - 0.5 * side, 0.0, c - 0.5 * side];
    scene.blocks[0].max = [c + 0.5 * side, height, c + 0.5 * side];
    let mut world = scene.build_world().unwrap();
    let volume = f64::from(side * side * height);
    let rho_g = f64::from(scene.fluid.rest_density) * 9.81;
    let k = 0.894 * (rho_g * volume.powi(3) / (3.0 * f64::from(mu))).powf(0.125);
    let centre = Vec3::new(c, 0.0, c);
    let mut rows = Vec::new();
    let mut t = 1.0f64;
    while t <= 4.0 + 1e-9 {
        while world.time() < t - 1e-9 {
            let r = world
                .advance(((t - world.time()) as f32).min(1.0 / 60.0))
                .unwrap();
            assert_eq!(r.unconverged, 0, "μ = {mu}: {r:?}");
        }
        let r = radius(world.particles.positions(), centre, scene.fluid.h);
        rows.push((t, f64::from(r), k * t.powf(0.125)));
        t *= 2.0f64.sqrt();
    }
    rows
}

/// Measured (this test's output): within 3.1 % at μ = 100 Pa·s and
/// 5.2 % at 1,000 from t = 1 s on. Before 1 s the block's corners, 0.14 m
/// from its centre, lead (+13 % at 0.5 s for 1,000 Pa·s). What this does
/// not show: over the window the radius grows only from 0.17 to 0.21 m at
/// 100 Pa·s and from 0.14 to 0.15 m at 1,000 (r ∝ t^{1/8}), and by 4 s the
/// thinner current is 3 particles thick, so a finer spacing and longer
/// times would test the law harder.
#[test]
fn axisymmetric_current_spreads_as_huppert() {
    for mu in [100.0f32, 1000.0] {
        let rows = spread(mu);
        println!("μ = {mu} Pa·s: t (s), r (m), Huppert (m)");
        for &(t, r, theory) in &rows {
            println!(
                "  {t:5.2} {r:.4} {theory:.4} ({:+.1} %)",
                100.0 * (r / theory - 1.0)
            );
        }
        for (t, r, theory) in rows {
            assert!(
                (r / theory - 1.0).abs() <= 0.10,
                "μ = {mu}, t = {t}: r {r} m, Huppert {theory} m"
            );
        }
    }
}
