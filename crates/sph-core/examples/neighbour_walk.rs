//! Visits every neighbour of every particle of a jittered 46³ lattice
//! (97,336 particles, h = 2 spacings) `ROUNDS` times on one thread through
//! [`NeighbourGrid::for_each_neighbour`], and prints the pair count and
//! Σ r². Under callgrind it counts the instructions of the neighbour scan
//! and its caller's hit loop, which the noisy VM's timings cannot resolve
//! to a few per cent:
//!
//! ```text
//! cargo build --release -p sph-core --example neighbour_walk
//! SPH_SIMD=avx2 valgrind --tool=callgrind target/release/examples/neighbour_walk [ROUNDS]
//! ```
//!
//! ROUNDS defaults to 5.

use sph_core::NeighbourGrid;
use sph_core::glam::Vec3;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let rounds: usize = match std::env::args().nth(1) {
        Some(a) => a.parse().map_err(|e| format!("ROUNDS {a:?}: {e}"))?,
        None => 5,
    };
    let (n, spacing) = (46usize, 0.01f32);
    // xorshift32: the same jitter on every run and every machine.
    let mut state = 0x9E37_79B9u32;
    let mut jitter = || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        0.2 * (state as f32 / u32::MAX as f32 - 0.5)
    };
    let mut x = Vec::with_capacity(n * n * n);
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let at = Vec3::new(
                    i as f32 + jitter(),
                    j as f32 + jitter(),
                    k as f32 + jitter(),
                );
                x.push(at * spacing);
            }
        }
    }
    let grid = NeighbourGrid::build(&x, 2.0 * spacing)?;
    let (mut pairs, mut sum) = (0u64, 0f64);
    for _ in 0..rounds {
        for i in 0..x.len() {
            grid.for_each_neighbour(i, |_, _, r2| {
                pairs += 1;
                sum += f64::from(r2);
            });
        }
    }
    println!(
        "{} particles, {rounds} rounds: {pairs} pairs, Σ r² = {sum:.6e}",
        x.len()
    );
    Ok(())
}
