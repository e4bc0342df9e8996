//! Sorted against shuffled input for the neighbour grid: build + full
//! neighbour enumeration of a 1M-particle cube at spacing h/2, the same
//! particles in lattice order and in a fixed random order, median of 15.
//!
//! `cargo run --release -p sph-core --example shuffled_input`
//!
//! Uses only API that older commits have too, so it can be copied into an
//! old checkout to compare (see `docs/benchmark-notes.md`, "`neighbours`").

use std::time::Instant;

use sph_core::NeighbourGrid;
use sph_core::glam::Vec3;

const H: f32 = 0.02;

/// The bench's fixed shuffle (benches/neighbours.rs).
fn shuffled(mut p: Vec<Vec3>) -> Vec<Vec3> {
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    for i in (1..p.len()).rev() {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        let j = (state >> 33) as usize % (i + 1);
        p.swap(i, j);
    }
    p
}

/// Ordered neighbour pairs (i, j), i ≠ j, from a fresh grid.
fn pairs(positions: &[Vec3]) -> u64 {
    let grid = NeighbourGrid::build(positions, H).expect("a valid cube");
    let per = grid.par_map(|i, nb| {
        let mut n = 0u32;
        nb.for_each(|j, _, _| n += u32::from(j != i));
        n
    });
    per.iter().map(|&n| u64::from(n)).sum()
}

fn main() {
    let n = 100;
    let mut sorted = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                sorted.push(Vec3::new(i as f32, j as f32, k as f32) * (H / 2.0));
            }
        }
    }
    let mixed = shuffled(sorted.clone());
    for (name, points) in [("sorted", &sorted), ("shuffled", &mixed)] {
        let count = pairs(points);
        let mut ms: Vec<f64> = (0..15)
            .map(|_| {
                let start = Instant::now();
                std::hint::black_box(pairs(points));
                start.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        ms.sort_by(f64::total_cmp);
        println!(
            "{name}: {count} pairs, median {:.1} ms (fastest {:.1})",
            ms[7], ms[0]
        );
    }
}
