//! What more than one example uses.

use sph_core::{NeighbourGrid, NeighbourLists};

/// The size of each particle's cluster: connected components of the graph
/// linking particles within h (union–find over the neighbour lists).
pub fn cluster_sizes(positions: &[sph_core::glam::Vec3], h: f32) -> sph_core::Result<Vec<usize>> {
    let grid = NeighbourGrid::build(positions, h)?;
    let lists = NeighbourLists::build(&grid)?;
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
