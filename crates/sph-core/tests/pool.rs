//! Water at rest (issue 41): a pool filled on the lattice from the floor,
//! still from the start, under each solver.

use sph_core::{Scene, SolverKind, World};

/// Spacing (m); h = 2 spacings.
const S: f32 = 0.02;

/// A pool `side` square and `depth` deep, particle centres kept `clearance`
/// from the walls, run by `kind` for `seconds` of 60 Hz frames.
fn settled(kind: SolverKind, side: f32, depth: f32, clearance: f32, seconds: f32) -> World {
    let mut scene = Scene::dam_break(0.15, side, S).with_solver(kind);
    scene.domain.min = [0.0; 3];
    scene.domain.max = [side, depth + 0.1, side];
    scene.blocks[0].min = [0.0; 3];
    scene.blocks[0].max = [side, depth, side];
    scene.clearance = clearance;
    let mut world = scene.build_world().unwrap();
    for _ in 0..(seconds * 60.0).round() as usize {
        world.advance(1.0 / 60.0).unwrap();
    }
    world
}

/// The mean height (m) of the particles below one spacing, more than 2h
/// from the side walls.
fn first_layer(world: &World, side: f32) -> f32 {
    let inside = |c: f32| c > 4.0 * S && c < side - 4.0 * S;
    let heights: Vec<f32> = (world.particles.positions().iter())
        .filter(|x| x.y < S && inside(x.x) && inside(x.z))
        .map(|x| x.y)
        .collect();
    assert!(!heights.is_empty());
    heights.iter().sum::<f32>() / heights.len() as f32
}

/// With a clearance of half a spacing, the first layer of every solver
/// rests within 10 % of half a spacing above the floor, where the lattice
/// put it. (Without one it sinks to 1–4 mm of its 10: `cargo run --release
/// -p sph-core --example pool_at_rest`.)
#[test]
fn the_first_layer_rests_half_a_spacing_above_the_floor() {
    for kind in SolverKind::ALL {
        let (side, depth) = (0.3, 0.2);
        let world = settled(kind, side, depth, 0.5 * S, 1.0);
        let layer = first_layer(&world, side);
        eprintln!("{kind}: first layer {:.2} mm", 1e3 * layer);
        assert!(
            (layer / (0.5 * S) - 1.0).abs() <= 0.1,
            "{kind}: first layer at {:.2} mm, half a spacing is {:.0} mm",
            1e3 * layer,
            500.0 * S
        );
    }
}
