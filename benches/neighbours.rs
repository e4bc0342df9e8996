//! `cargo bench --bench neighbours`: build + full neighbour enumeration over a block
//! of particles at spacing h/2 (about 33 neighbours each), for `sph_core`'s
//! [`NeighbourGrid`] and two baselines a user would otherwise reach for:
//!
//! - `hashmap`: a `HashMap<[i32; 3], Vec<usize>>` cell → particles grid (the layout
//!   salva uses), built sequentially, queried in parallel over the 27 cells;
//! - `kiddo`: kiddo's `ImmutableKdTree`, built in parallel, one unsorted radius
//!   query per particle in parallel.
//!
//! The grid is timed twice: built fresh each iteration (`sph-core grid`), and
//! rebuilt in place with `NeighbourGrid::rebuild` (`sph-core grid rebuild`), the
//! way a solver uses it every step, reusing its memory.
//!
//! Every method does the same work per particle: count its neighbours j ≠ i with
//! |x_i − x_j|² ≤ h² and sum their r², so nothing can be optimised away. Throughput
//! is in neighbour pairs: ordered pairs (i, j), i ≠ j, the visits an SPH gather makes.
//! The block is generated x fastest, the order a user creating it has; at 1M the
//! grid is also timed on the same particles shuffled (`shuffled`), where input
//! order gives no locality.

use std::collections::HashMap;
use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use sph_core::NeighbourGrid;

const H: f32 = 0.02;

/// A cube of about `n` particles at spacing h/2, x fastest.
fn block(n: usize) -> Vec<Vec3> {
    let side = (n as f64).cbrt().round() as usize;
    let spacing = H / 2.0;
    let mut p = Vec::with_capacity(side * side * side);
    for k in 0..side {
        for j in 0..side {
            for i in 0..side {
                p.push(Vec3::new(i as f32, j as f32, k as f32) * spacing);
            }
        }
    }
    p
}

/// The same particles in a deterministic random order (Fisher-Yates, 64-bit LCG).
fn shuffled(mut p: Vec<Vec3>) -> Vec<Vec3> {
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    for i in (1..p.len()).rev() {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        p.swap(i, (state >> 33) as usize % (i + 1));
    }
    p
}

/// (pairs, Σ r²) with sph-core's grid, built fresh.
fn grid_pairs(positions: &[Vec3]) -> (u64, f64) {
    let grid = NeighbourGrid::build(positions, H).expect("valid block");
    enumerate(&grid)
}

/// (pairs, Σ r²) with sph-core's grid rebuilt in place, as a solver does every
/// step (no allocation once the buffers have grown).
fn grid_rebuild_pairs(grid: &mut NeighbourGrid, positions: &[Vec3]) -> (u64, f64) {
    grid.rebuild(positions).expect("valid block");
    enumerate(grid)
}

/// Visits every neighbour pair of the grid's particles.
fn enumerate(grid: &NeighbourGrid) -> (u64, f64) {
    let per = grid.par_map(|i, nb| {
        let (mut n, mut s) = (0u32, 0.0f32);
        nb.for_each(|j, _, r2| {
            if j != i {
                n += 1;
                s += r2;
            }
        });
        (n, s)
    });
    per.iter()
        .fold((0, 0.0), |(n, s), &(a, b)| (n + a as u64, s + b as f64))
}

/// (pairs, Σ r²) with a HashMap<cell, Vec<index>> grid.
fn hashmap_pairs(positions: &[Vec3]) -> (u64, f64) {
    let cell = |p: Vec3| (p / H).floor().as_ivec3().to_array();
    let mut map: HashMap<[i32; 3], Vec<usize>> = HashMap::new();
    for (i, &p) in positions.iter().enumerate() {
        map.entry(cell(p)).or_default().push(i);
    }
    let h2 = H * H;
    let per: Vec<(u32, f32)> = positions
        .par_iter()
        .enumerate()
        .map(|(i, &p)| {
            let c = cell(p);
            let (mut n, mut s) = (0u32, 0.0f32);
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        if let Some(list) = map.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                            for &j in list {
                                let r2 = (p - positions[j]).length_squared();
                                if r2 <= h2 && j != i {
                                    n += 1;
                                    s += r2;
                                }
                            }
                        }
                    }
                }
            }
            (n, s)
        })
        .collect();
    per.iter()
        .fold((0, 0.0), |(n, s), &(a, b)| (n + a as u64, s + b as f64))
}

/// (pairs, Σ r²) with kiddo's immutable k-d tree.
fn kiddo_pairs(positions: &[Vec3]) -> (u64, f64) {
    let points: Vec<[f32; 3]> = positions.iter().map(|p| p.to_array()).collect();
    let tree: ImmutableKdTree<f32, 3> =
        ImmutableKdTree::new_from_slice_parallel(&points).expect("valid points");
    let h2 = H * H;
    let per: Vec<(u32, f32)> = points
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let found = tree
                .query(p)
                .within::<SquaredEuclidean<f32>>(h2)
                .unsorted()
                .execute();
            let (mut n, mut s) = (0u32, 0.0f32);
            for r in found {
                if r.item as usize != i {
                    n += 1;
                    s += r.distance;
                }
            }
            (n, s)
        })
        .collect();
    per.iter()
        .fold((0, 0.0), |(n, s), &(a, b)| (n + a as u64, s + b as f64))
}

fn neighbours(c: &mut Criterion) {
    let mut group = c.benchmark_group("neighbours");
    for n in [10_000usize, 100_000, 1_000_000] {
        let positions = block(n);
        let (pairs, _) = grid_pairs(&positions);
        // All three methods must agree before any is timed.
        assert_eq!(hashmap_pairs(&positions).0, pairs, "hashmap disagrees");
        assert_eq!(kiddo_pairs(&positions).0, pairs, "kiddo disagrees");
        println!(
            "{} particles: {pairs} neighbour pairs ({:.1} per particle)",
            positions.len(),
            pairs as f64 / positions.len() as f64
        );
        group.throughput(Throughput::Elements(pairs));
        group.sample_size(if n >= 1_000_000 { 10 } else { 20 });
        let label = positions.len();
        group.bench_with_input(
            BenchmarkId::new("sph-core grid", label),
            &positions,
            |b, p| b.iter(|| black_box(grid_pairs(p))),
        );
        let mut grid = NeighbourGrid::build(&[], H).expect("valid h");
        assert_eq!(grid_rebuild_pairs(&mut grid, &positions).0, pairs);
        group.bench_with_input(
            BenchmarkId::new("sph-core grid rebuild", label),
            &positions,
            |b, p| b.iter(|| black_box(grid_rebuild_pairs(&mut grid, p))),
        );
        group.bench_with_input(
            BenchmarkId::new("hashmap grid", label),
            &positions,
            |b, p| b.iter(|| black_box(hashmap_pairs(p))),
        );
        group.bench_with_input(
            BenchmarkId::new("kiddo kd-tree", label),
            &positions,
            |b, p| b.iter(|| black_box(kiddo_pairs(p))),
        );
        if n >= 1_000_000 {
            let mixed = shuffled(positions.clone());
            assert_eq!(grid_pairs(&mixed).0, pairs);
            group.bench_with_input(
                BenchmarkId::new("sph-core grid shuffled", label),
                &mixed,
                |b, p| b.iter(|| black_box(grid_pairs(p))),
            );
        }
    }
    group.finish();
}

criterion_group!(benches, neighbours);
criterion_main!(benches);
