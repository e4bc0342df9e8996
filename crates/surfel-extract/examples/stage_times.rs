//! Where an extraction's time goes, on the `extraction` bench's frames: the
//! medians of `Stats`' stage times (field, initial guess, refinement, hole
//! closing) over repeated runs, for the one-shot `extract` and for an
//! `Extractor` kept across runs (interleaved), and a fingerprint of the surfels, so a change
//! meant to leave the result as it is can be checked bitwise.
//!
//! ```sh
//! cargo run --release -p surfel-extract --example stage_times [-- 100k|drop] [anisotropic] [ITERATIONS] [RUNS]
//! ```
//!
//! Defaults: the 2,250-particle frame, the isotropic field, 2 iterations,
//! 21 runs. `drop` takes the scene file `assets/scenes/drop_into_pool.toml`
//! instead (the demo's default `drop`, a cube falling into a pool by PBF,
//! plus an emitter) at 2 s, about 7,000 particles with its splash, at the
//! scene's h.

use sph_core::{Particles, Scene};
use surfel_extract::{ExtractParams, Extractor, Surface, extract};

/// The dam break `Scene::dam_break(a, depth, 0.01)` after `t` seconds.
fn frame(a: f32, depth: f32, t: f32) -> Result<Particles, Box<dyn std::error::Error>> {
    let mut world = Scene::dam_break(a, depth, 0.01).build_world()?;
    world.advance(t)?;
    Ok(world.particles)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (label, particles, h) = if args.iter().any(|a| a == "100k") {
        ("100k", frame(0.37, 0.37, 0.1)?, 0.02)
    } else if args.iter().any(|a| a == "drop") {
        let scene = Scene::load(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../assets/scenes/drop_into_pool.toml"
        ))?;
        let mut world = scene.build_world()?;
        world.advance(2.0)?;
        ("drop", world.particles, scene.fluid.h)
    } else {
        ("2k", frame(0.15, 0.05, 0.3)?, 0.02)
    };
    let mut numbers = args.iter().filter_map(|a| a.parse::<u32>().ok());
    let iterations = numbers.next().unwrap_or(2);
    let runs = numbers.next().unwrap_or(21).max(1) as usize;
    let surface = if args.iter().any(|a| a == "anisotropic") {
        Surface::anisotropic()
    } else {
        Surface::Isotropic
    };
    let params = ExtractParams {
        iterations,
        surface,
        ..ExtractParams::new(h)
    };
    let out = extract(&particles, &params)?;
    // FNV-1a over every surfel's bits.
    let mut fingerprint = 0xcbf2_9ce4_8422_2325u64;
    for s in &out.surfels {
        for v in [s.position.to_array(), s.normal.to_array()]
            .concat()
            .into_iter()
            .chain([s.radius])
        {
            for byte in v.to_bits().to_le_bytes() {
                fingerprint = (fingerprint ^ byte as u64).wrapping_mul(0x100_0000_01b3);
            }
        }
    }
    println!(
        "{label} ({} particles), {surface:?}, {iterations} iterations: {} surfels ({} from hole closing), fingerprint {fingerprint:016x}",
        particles.len(),
        out.stats.surfels,
        out.stats.filled,
    );
    let s = &out.stats;
    println!(
        "  {} surface particles, {} all around, {} droplets; {} initial surfels, {} discarded; evaluations: {} in the initial guess, {} in refinement and hole closing",
        s.surface_particles,
        s.all_around,
        s.droplets,
        s.initial,
        s.discarded,
        s.particle_evaluations,
        s.evaluations,
    );
    // Both ways interleaved, run for run: the one-shot `extract` (fresh
    // memory every call) and an `Extractor` kept across calls.
    let mut extractor = Extractor::new();
    let reused = extractor.extract(&particles, &params)?;
    assert_eq!(reused.surfels, out.surfels, "Extractor and extract differ");
    let mut times: [Vec<[f64; 5]>; 2] = Default::default();
    for _ in 0..runs {
        let one_shot = extract(&particles, &params)?.stats;
        let kept = extractor.extract(&particles, &params)?.stats;
        for (t, s) in times.iter_mut().zip([one_shot, kept]) {
            t.push(
                [
                    s.field_time,
                    s.initial_time,
                    s.refine_time,
                    s.fill_time,
                    s.total_time(),
                ]
                .map(|d| d.as_secs_f64() * 1e3),
            );
        }
    }
    let names = [
        "field",
        "initial guess",
        "refinement",
        "hole closing",
        "total",
    ];
    for (way, times) in ["extract", "Extractor"].iter().zip(&times) {
        print!("{way:>9}: medians of {runs} runs (ms):");
        for (k, name) in names.iter().enumerate() {
            let mut column: Vec<f64> = times.iter().map(|t| t[k]).collect();
            column.sort_by(f64::total_cmp);
            print!(" {name} {:.2}", column[runs / 2]);
        }
        println!();
    }
    Ok(())
}
