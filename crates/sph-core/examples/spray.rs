//! Spray: the fraction of particles in small clusters (at most 10 particles,
//! linked where closer than h) of the `drop` scene (the demo's key 4,
//! `Scene::drop_into_pool(0.2, 0.02)`) at t = 0.5 s, for each solver.
//!
//! ```text
//! cargo run --release -p sph-core --example spray
//! ```

use sph_core::{NeighbourGrid, NeighbourLists, Scene, SolverKind};

/// The size of each particle's cluster: connected components of the graph
/// linking particles within h (union–find over the neighbour lists).
fn cluster_sizes(positions: &[sph_core::glam::Vec3], h: f32) -> sph_core::Result<Vec<usize>> {
    let grid = NeighbourGrid::build(positions, h)?;
    let lists = NeighbourLists::build(&grid);
    let mut parent: Vec<usize> = (0..positions.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for i in 0..positions.len() {
        for &j in lists.of(i) {
            let (a, b) = (root(&mut parent, i), root(&mut parent, j as usize));
            if a != b {
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let roots: Vec<usize> = (0..positions.len()).map(|i| root(&mut parent, i)).collect();
    let mut size = vec![0usize; positions.len()];
    for &r in &roots {
        size[r] += 1;
    }
    Ok(roots.iter().map(|&r| size[r]).collect())
}

fn main() -> sph_core::Result<()> {
    for kind in SolverKind::ALL {
        let scene = Scene::drop_into_pool(0.2, 0.02).with_solver(kind);
        let mut world = scene.build_world()?;
        let mut substeps = 0;
        for _ in 0..30 {
            substeps += world.advance(1.0 / 60.0)?.substeps;
        }
        let sizes = cluster_sizes(world.particles.positions(), world.params().h)?;
        let n = sizes.len();
        let small = sizes.iter().filter(|&&s| s <= 10).count();
        let lone = sizes.iter().filter(|&&s| s == 1).count();
        println!(
            "{kind:<6} t = {:.2} s ({substeps} substeps): {small} of {n} particles in clusters of ≤ 10 ({:.1} %), {lone} alone",
            world.time(),
            100.0 * small as f64 / n as f64
        );
    }
    Ok(())
}
