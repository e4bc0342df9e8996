//! The dam break against Martin & Moyce's experiment: the surge front of a
//! water column of width a and height 2a over time, non-dimensional, for
//! every solver.
//!
//! ```text
//! cargo test --release -p sph-core --test dam_break_experiment -- --nocapture
//! ```

use sph_core::glam::Vec3;
use sph_core::{NeighbourGrid, NeighbourLists, Scene, SolverKind};

/// Martin & Moyce (1952), "An experimental study of the collapse of liquid
/// columns on a rigid horizontal plane", Phil. Trans. R. Soc. A 244,
/// 312–324, Fig. 3: n² = 2 (height 2a), a = 2.25 in, as digitised in
/// PySPH's `examples/db_exp_data.py`. Pairs (T, Z): T = t √(2g/a), Z = z/a
/// with z the front's distance from the column's back wall (1 at t = 0).
const MARTIN_MOYCE: [(f32, f32); 15] = [
    (0.832, 1.217),
    (1.219, 1.474),
    (1.997, 2.292),
    (2.547, 2.995),
    (3.345, 4.134),
    (4.034, 4.944),
    (4.418, 5.881),
    (5.091, 6.980),
    (5.685, 7.945),
    (6.306, 8.966),
    (6.822, 9.986),
    (7.439, 10.963),
    (8.031, 11.977),
    (8.633, 13.005),
    (9.237, 13.970),
];

/// The column's width a (m): the demo's slab dam break.
const A: f32 = 0.25;

/// The front: the largest x of the particles with at least 5 neighbours
/// within h, so that a lone droplet ahead of the flow does not count.
fn front(positions: &[Vec3], h: f32) -> f32 {
    let grid = NeighbourGrid::build(positions, h).unwrap();
    let lists = NeighbourLists::build(&grid).unwrap();
    (0..positions.len())
        .filter(|&i| lists.of(i).len() >= 5)
        .map(|i| positions[i].x)
        .fold(f32::MIN, f32::max)
}

/// The solver's Z at each of the experiment's T within a flume `length`
/// long (while the front is more than h from its end), and the mean
/// relative error |Z − Z_exp| / Z_exp over those points.
fn surge(kind: SolverKind, spacing: f32, length: f32) -> (Vec<(f32, f32, f32)>, f32) {
    let mut scene = Scene::dam_break(A, 0.08, spacing).with_solver(kind);
    // Water (PBF's XSPH viscosity has no μ), and a flume long enough for
    // the experiment's range.
    if kind != SolverKind::Pbf {
        scene.fluid.viscosity = Some(1e-3);
    }
    scene.domain.max[0] = length;
    let mut world = scene.build_world().unwrap();
    let h = scene.fluid.h;
    // Land on each of the experiment's times: T = t √(2g/a).
    let scale = (2.0 * 9.81 / A).sqrt();
    let mut rows = Vec::new();
    for &(t_exp, z_exp) in &MARTIN_MOYCE {
        let t = f64::from(t_exp / scale);
        let step = t - world.time();
        world.advance(step as f32).unwrap();
        let x = front(world.particles.positions(), h);
        if x > length - h {
            break;
        }
        rows.push((t_exp, z_exp, x / A));
    }
    let error = rows
        .iter()
        .map(|&(_, z_exp, z)| (z - z_exp).abs() / z_exp)
        .sum::<f32>()
        / rows.len() as f32;
    (rows, error)
}

/// Each solver's table and mean relative error at `spacing`.
fn report(kinds: &[SolverKind], spacing: f32) -> Vec<(SolverKind, f32, usize)> {
    let length = 16.0 * A;
    let mut errors = Vec::new();
    for &kind in kinds {
        let (rows, error) = surge(kind, spacing, length);
        println!("{kind}, spacing {spacing} m, μ = 1e-3 Pa·s: T, Z (experiment), Z ({kind})");
        for (t, z_exp, z) in &rows {
            println!(
                "  {t:6.3} {z_exp:7.3} {z:7.3} ({:+.1} %)",
                100.0 * (z / z_exp - 1.0)
            );
        }
        println!(
            "  mean relative error {:.1} % over {} points",
            100.0 * error,
            rows.len()
        );
        errors.push((kind, error, rows.len()));
    }
    errors
}

/// The demo's resolution (1,200 particles), the flume lengthened to 16a so
/// that the front stays clear of its end over the experiment's whole range
/// (T ≤ 9.2). Measured (this test's output): mean relative error 6.0 %
/// for DFSPH, 2.2 % for PBF, 5.0 % for WCSPH (6.2, 2.1 and 6.8 % while the
/// walls' layers were V^⅓ apart). Each is asserted at the measured error
/// plus about 1.2 points, within the 10 % goal, so that it gets no worse
/// unnoticed. (Without the scenes' clearance WCSPH's front
/// ran 40–65 % ahead up to T = 3.3, 26.7 % in all: its first step kicked
/// the column's over-dense wall and corner particles; DFSPH read 6.8 % and
/// PBF 1.8 %.)
#[test]
fn surge_front_against_martin_and_moyce() {
    let errors = report(
        &[SolverKind::Dfsph, SolverKind::Pbf, SolverKind::Wcsph],
        0.02,
    );
    for (kind, error, points) in errors {
        assert_eq!(points, MARTIN_MOYCE.len(), "{kind}");
        let bound = match kind {
            SolverKind::Dfsph => 0.072,
            SolverKind::Pbf => 0.034,
            SolverKind::Wcsph => 0.062,
        };
        assert!(error <= bound, "{kind}: mean relative error {error}");
    }
}

/// The same at 1 cm spacing (`dam-break-fine`'s 10,000 particles), DFSPH
/// and PBF (about 10 s on 2 cores):
/// `cargo test --release -p sph-core --test dam_break_experiment -- --nocapture`.
///
/// Measured: DFSPH 11.1 %, PBF 7.6 % (11.8 and 7.8 % without the scenes'
/// clearance), asserted at 12.5 and 9 %. DFSPH
/// misses the 10 % goal here:
/// its front runs 9–18 % ahead from the first point on, more than at the
/// coarser spacing (less smoothing). From T = 4.4 on its front moves at
/// dZ/dT = 1.91, 0.95 of Ritter's inviscid 2, where the experiment's
/// moves at 1.68 (0.84). What slows the real front is not in the
/// simulation: the walls are no-slip, but water's μ = 1e-3 Pa·s gives a
/// laminar boundary layer far thinner than a spacing (the experiment's is
/// turbulent), and the experiment's column started with the removal of a
/// gate, which the simulation's instant start skips. A wall-friction
/// model would slow it; none is attempted.
#[test]
fn surge_front_fine() {
    for (kind, error, points) in report(&[SolverKind::Dfsph, SolverKind::Pbf], 0.01) {
        assert_eq!(points, MARTIN_MOYCE.len(), "{kind}");
        let bound = if kind == SolverKind::Dfsph {
            0.125
        } else {
            0.09
        };
        assert!(error <= bound, "{kind}: mean relative error {error}");
    }
}
