//! `cargo bench --bench extraction`: the thesis's Table 2 — surfel extraction with
//! 1, 2 and 3 refinement iterations and the LDC reference — on a 2,250-particle
//! dam-break frame (the thesis's size) and a 101k-particle one. Each timed run
//! includes building the colour field (grid and volumes) from the particles.
//! Throughput is in surfels. Before timing, one untimed run per configuration
//! prints surfels, evaluations and efficiency (surfels per surfel evaluation).

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use sph_core::{Particles, Scene};
use surfel_extract::ldc::extract_ldc;
use surfel_extract::{ColourField, ExtractParams, extract};

/// The dam break `Scene::dam_break(a, depth, 0.01)` after `t` seconds.
fn frame(a: f32, depth: f32, t: f32) -> Particles {
    let mut world = Scene::dam_break(a, depth, 0.01)
        .build_world()
        .expect("built-in scene");
    world.advance(t).expect("stable");
    world.particles
}

fn extraction(c: &mut Criterion) {
    let mut group = c.benchmark_group("extraction");
    group.sample_size(10);
    for (label, particles) in [
        ("2k", frame(0.15, 0.05, 0.3)),
        ("100k", frame(0.37, 0.37, 0.1)),
    ] {
        let h = 0.02;
        for iterations in 1..=3 {
            let params = ExtractParams {
                iterations,
                ..ExtractParams::new(h)
            };
            let out = extract(&particles, &params).expect("extraction");
            let s = out.stats;
            println!(
                "{label} ({} particles), {iterations} iterations: {} surfels, {} surfel + {} particle evaluations, efficiency {:.2}",
                particles.len(),
                s.surfels,
                s.evaluations,
                s.particle_evaluations,
                s.efficiency()
            );
            group.throughput(Throughput::Elements(s.surfels as u64));
            group.bench_function(
                BenchmarkId::new(format!("{label}/iterations"), iterations),
                |b| b.iter(|| black_box(extract(&particles, &params).expect("extraction"))),
            );
        }
        let params = ExtractParams::new(h);
        let ldc = |p: &Particles| {
            let field = ColourField::from_particles(p, h).expect("field");
            extract_ldc(&field, &params, 0.5 * h).expect("ldc")
        };
        let out = ldc(&particles);
        println!(
            "{label} LDC at h/2: {} surfels, {} evaluations, efficiency {:.2}",
            out.stats.surfels,
            out.stats.evaluations,
            out.stats.efficiency()
        );
        group.throughput(Throughput::Elements(out.stats.surfels as u64));
        group.bench_function(BenchmarkId::new(label, "ldc"), |b| {
            b.iter(|| black_box(ldc(&particles)))
        });
    }
    group.finish();
}

criterion_group!(benches, extraction);
criterion_main!(benches);
