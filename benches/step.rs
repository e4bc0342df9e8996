//! `cargo bench --bench step`: one SPH step (grid, density/pressure, forces,
//! integration, boundaries) of the full-3D dam break (`Scene::dam_break(a, a,
//! 0.01)`, h = 2 × spacing) at about 10k and 100k particles, on all threads and,
//! as the baseline in the same run, on one rayon thread. Throughput is in
//! particle-steps per second.
//!
//! Each benchmark starts from the column after 0.1 s of simulated collapse (so
//! the fluid is moving and the particles are in grid order, as during a run) and
//! steps on from there; the state drifts by a few ms of simulated time per
//! sample, which does not change the work per step.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use sph_core::{Scene, World};

/// The dam break with a column `a` wide and deep, settled for 0.1 s.
fn dam_break(a: f32) -> World {
    let mut world = Scene::dam_break(a, a, 0.01)
        .build_world()
        .expect("built-in scene");
    world.advance(0.1).expect("stable");
    world
}

fn step(c: &mut Criterion) {
    let mut group = c.benchmark_group("step");
    group.sample_size(10);
    let threads = rayon::current_num_threads();
    for (label, a) in [("10k", 0.17f32), ("100k", 0.37)] {
        let world = dam_break(a);
        let n = world.particles.len();
        group.throughput(Throughput::Elements(n as u64));
        for t in [1, threads] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(t)
                .build()
                .expect("thread pool");
            let mut w = dam_break(a);
            // The step on every thread of the pool, past `useful_threads`.
            w.use_every_thread(true);
            let id = BenchmarkId::new(format!("{label}/threads"), t);
            group.bench_function(id, |b| {
                b.iter(|| pool.install(|| black_box(w.step().expect("stable"))))
            });
        }
        println!("{label}: {n} particles");
    }
    group.finish();
}

criterion_group!(benches, step);
criterion_main!(benches);
