//! Divergence-free SPH against physics: a hydrostatic tank (density error,
//! pressure against ρ0 g depth, rest), the dam break's compression,
//! determinism across threads, and bad input.

use sph_core::{DfsphParams, Particles, Scene, SolverKind, World};

/// A tank `w` wide, 0.08 m deep, filled to `depth`, run by DFSPH.
fn tank(w: f32, depth: f32, dfsph: DfsphParams) -> Scene {
    let spacing = 0.02;
    let mut scene = Scene::dam_break(w, 0.08, spacing).with_solver(SolverKind::Dfsph);
    scene.domain.max = [w, depth + 0.1, 0.08];
    scene.blocks[0].max = [w, depth, 0.08];
    scene.solver.dfsph = Some(dfsph);
    scene
}

fn rms_speed(p: &Particles) -> f32 {
    let sum: f64 = p
        .velocities()
        .iter()
        .map(|v| f64::from(v.length_squared()))
        .sum();
    (sum / p.len() as f64).sqrt() as f32
}

/// Whether every particle is inside the domain and out of the obstacles.
fn contained(world: &World, scene: &Scene) -> bool {
    let boundary = scene.boundary();
    world
        .particles
        .positions()
        .iter()
        .all(|&x| boundary.admits(x))
}

/// The least-squares slope of p over y.
fn slope(ys: &[f32], ps: &[f32]) -> f64 {
    let n = ys.len() as f64;
    let my = ys.iter().map(|&y| f64::from(y)).sum::<f64>() / n;
    let mp = ps.iter().map(|&p| f64::from(p)).sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (&y, &p) in ys.iter().zip(ps) {
        let dy = f64::from(y) - my;
        sxy += dy * (f64::from(p) - mp);
        sxx += dy * dy;
    }
    sxy / sxx
}

#[test]
fn hydrostatic_tank() {
    let scene = tank(0.3, 0.2, DfsphParams::default());
    let mut world = scene.build_world().unwrap();
    let n = world.particles.len();
    let (mut worst_avg, mut worst_max) = (0.0f32, 0.0f32);
    for frame in 0..120 {
        let r = world.advance(1.0 / 60.0).unwrap();
        assert_eq!(r.solver, SolverKind::Dfsph);
        println!(
            "frame {frame}: {} steps, dt {:.2e}..{:.2e}, {} + {} iterations, {} unconverged, error {:.4} % avg {:.3} % max",
            r.substeps,
            r.dt_range.0,
            r.dt_range.1,
            r.iterations,
            r.divergence_iterations,
            r.unconverged,
            100.0 * r.density_error_avg,
            100.0 * r.density_error_max
        );
        if frame >= 60 {
            worst_avg = worst_avg.max(r.density_error_avg);
            worst_max = worst_max.max(r.density_error_max);
        }
    }
    let p = &world.particles;
    let h = scene.fluid.h;
    {
        let mut idx: Vec<usize> = (0..p.len()).collect();
        idx.sort_by(|&a, &b| p.densities()[b].total_cmp(&p.densities()[a]));
        for &i in &idx[..8] {
            println!("dense {i}: x {:?} rho {} v {:?}", p.positions()[i], p.densities()[i], p.velocities()[i]);
        }
        for layer in 0..12 {
            let y0 = layer as f32 * 0.02;
            let sel: Vec<usize> = (0..p.len()).filter(|&i| (p.positions()[i].y - y0).abs() < 0.01).collect();
            let rms = (sel.iter().map(|&i| p.velocities()[i].length_squared()).sum::<f32>() / sel.len().max(1) as f32).sqrt();
            let rho = sel.iter().map(|&i| p.densities()[i]).sum::<f32>() / sel.len().max(1) as f32;
            let pr = sel.iter().map(|&i| p.pressures()[i]).sum::<f32>() / sel.len().max(1) as f32;
            println!("layer y={y0:.2}: {} particles rms {rms:.4} rho {rho:.2} p {pr:.1}", sel.len());
        }
    }
    let (ys, ps): (Vec<f32>, Vec<f32>) = (p.positions().iter().zip(p.pressures()))
        .filter(|(x, _)| x.y > h && x.y < 0.2 - h)
        .map(|(x, &p)| (x.y, p))
        .unzip();
    let s = slope(&ys, &ps);
    let expected = -f64::from(scene.fluid.rest_density) * 9.81;
    let rms = rms_speed(p);
    println!(
        "{n} particles: worst error {:.4} % avg, {:.3} % max; slope {s:.1} Pa/m (ρ0 g = {:.1}); rms {rms:.5} m/s",
        100.0 * worst_avg,
        100.0 * worst_max,
        -expected
    );
    assert_eq!(world.particles.len(), n);
    assert!(contained(&world, &scene));
    assert!(worst_avg <= 0.001, "average density error {worst_avg}");
    assert!(worst_max <= 0.01, "largest density error {worst_max}");
    assert!((s / expected - 1.0).abs() <= 0.02, "slope {s} Pa/m");
    assert!(rms < 0.01, "rms speed {rms} m/s");
}
