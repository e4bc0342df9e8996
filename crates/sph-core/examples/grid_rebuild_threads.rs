//! How long rebuilding a neighbour grid takes on one thread and on two,
//! after a 50 µs serial gap such as the one between a solver's stations
//! (when rayon's idle workers have gone to sleep): the median of 400
//! rebuilds of jittered lattices of 1,728 to 97,336 particles. The rule in
//! `sph_core`'s light passes (below 32,768 particles a grid build and a
//! reordering run on the calling thread) comes from this table.
//!
//! ```text
//! cargo run --release -p sph-core --example grid_rebuild_threads
//! ```

use sph_core::NeighbourGrid;
use sph_core::glam::Vec3;
use std::time::Instant;
fn main() {
    for n_side in [12usize, 18, 22, 27, 34, 46] {
        let h = 0.02f32;
        let mut x = Vec::new();
        for k in 0..n_side {
            for j in 0..n_side {
                for i in 0..n_side {
                    let j2 = ((i * 7 + j * 13 + k * 3) % 10) as f32 * 0.0002;
                    x.push(Vec3::new(i as f32, j as f32, k as f32) * 0.01 + Vec3::splat(j2));
                }
            }
        }
        let mut row = format!("{:>7}", x.len());
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let t = pool.install(|| {
                let mut grid = NeighbourGrid::build(&x, h).unwrap();
                let mut times = Vec::new();
                for _ in 0..400 {
                    // a serial gap, as between stations
                    let s = Instant::now();
                    while s.elapsed().as_micros() < 50 {
                        std::hint::spin_loop();
                    }
                    let t = Instant::now();
                    grid.rebuild(&x).unwrap();
                    times.push(t.elapsed().as_secs_f64() * 1e3);
                }
                times.sort_by(f64::total_cmp);
                times[times.len() / 2]
            });
            row += &format!("  {threads}T {t:.3} ms");
        }
        println!("{row}");
    }
}
