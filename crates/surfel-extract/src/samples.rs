//! Particle sets for tests, examples and benches: jittered lattices, the same
//! on every machine.

use glam::Vec3;

/// A cubic lattice of `spacing` over the points (i, j, k) · spacing with i, j,
/// k in −n..=n, kept where `keep` holds for the lattice point, each kept point
/// moved by up to `jitter` × spacing per axis (a fluid is never a perfect
/// lattice). The offsets come from a fixed pseudo-random sequence started at
/// `seed`, drawn for every lattice point in z, y, x order, so a set depends
/// only on the arguments.
pub fn jittered_lattice(
    n: i32,
    spacing: f32,
    jitter: f32,
    seed: u64,
    keep: impl Fn(Vec3) -> bool,
) -> Vec<Vec3> {
    let mut seed = seed;
    let mut out = Vec::new();
    for k in -n..=n {
        for j in -n..=n {
            for i in -n..=n {
                let x = Vec3::new(i as f32, j as f32, k as f32) * spacing;
                let offset = Vec3::new(noise(&mut seed), noise(&mut seed), noise(&mut seed));
                if keep(x) {
                    out.push(x + jitter * spacing * offset);
                }
            }
        }
    }
    out
}

/// The next number in [−1, 1) of a 64-bit linear congruential sequence.
fn noise(seed: &mut u64) -> f32 {
    *seed = seed
        .wrapping_mul(6_364_136_223_846_793_005)
        .wrapping_add(1_442_695_040_888_963_407);
    ((*seed >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
}
