//! How the CPU path scales with threads (issue 45): for 1, 2, 4, 8 and 16
//! threads (those up to the machine's cores, or `--max-threads`), the
//! median wall time of a 1/60 s frame of PBF on the slab dam break at about
//! 10k and 100k particles and of DFSPH at 10k, and of the anisotropic
//! extraction (the demo's default surface) of the 10k and 100k frames, each
//! in a rayon pool of that many threads, with the speed-up over one thread.
//!
//! ```text
//! cargo run --release --example scaling [-- --frames F] [--max-threads N] [--sweep | --paired] [--every-thread]
//! ```
//!
//! `--sweep` instead times PBF frames at about 5k, 10k, 20k and 40k
//! particles and DFSPH at 10k for every even thread count up to the
//! cores: where a scene stops gaining from more threads.
//!
//! A `World` steps on at most `sph_core::useful_threads(n)` of the pool's
//! threads (max(8, n/3000)), so the default table shows what a user gets;
//! `--every-thread` (and `--sweep`) lifts that cap to time the step on
//! every thread of each pool.
//!
//! Each row starts from the scene's first frame and times `--frames` frames
//! (default 20) after two untimed ones; the extraction is timed five times
//! on the state the PBF rows end in.
//!
//! `--paired` times the steps of the default rows on a machine whose speed
//! drifts (a shared VM): one world per thread count, stepped in turn frame
//! by frame, so that each frame's times at every count are taken within
//! a fraction of a second of each other on the same state (the worlds are
//! bitwise equal). It prints the median ms and the median of the per-frame
//! speed-ups over one thread.

use std::time::Instant;

use sph_core::{Particles, Scene, SolverKind, World};
use surfel_extract::{ExtractParams, Extractor};

/// What a run can fail with (sent back from the pool's threads).
type Error = Box<dyn std::error::Error + Send + Sync>;

/// The median of `v` (sorted in place).
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Milliseconds per frame (median of `frames`, after two untimed ones) of
/// `scene` in the current pool, and the world it ends in.
fn frames(scene: &Scene, frames: usize, every: bool) -> Result<(f64, World), Error> {
    let mut world = scene.build_world()?;
    world.use_every_thread(every);
    for _ in 0..2 {
        world.advance(1.0 / 60.0)?;
    }
    let mut times = Vec::with_capacity(frames);
    for _ in 0..frames {
        let start = Instant::now();
        world.advance(1.0 / 60.0)?;
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    Ok((median(&mut times), world))
}

/// Milliseconds (median of five) of the anisotropic extraction of
/// `particles` at smoothing length `h`.
fn extraction(particles: &Particles, h: f32) -> Result<f64, Error> {
    let params = ExtractParams::new(h).anisotropic();
    let mut extractor = Extractor::new();
    extractor.extract(particles, &params)?;
    let mut times = Vec::new();
    for _ in 0..5 {
        let start = Instant::now();
        extractor.extract(particles, &params)?;
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    Ok(median(&mut times))
}

fn main() -> Result<(), Error> {
    let (mut count, mut max_threads, mut sweep, mut every) = (20usize, usize::MAX, false, false);
    let mut paired = false;
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = |name: &str| args.next().ok_or(format!("{name} needs a value"));
        match arg.as_str() {
            "--frames" => count = value("--frames")?.parse()?,
            "--max-threads" => max_threads = value("--max-threads")?.parse()?,
            "--sweep" => (sweep, every) = (true, true),
            "--every-thread" => every = true,
            "--paired" => paired = true,
            other => return Err(format!("unknown argument `{other}`").into()),
        }
    }
    if count == 0 {
        return Err("--frames must be at least 1".into());
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let counts: Vec<usize> = if sweep {
        [1, 2].into_iter().chain((4..=64).step_by(2)).collect()
    } else {
        vec![1, 2, 4, 8, 16]
    };
    let threads: Vec<usize> = counts
        .into_iter()
        .filter(|&n| n <= cores.min(max_threads))
        .collect();
    let pbf = |spacing| Scene::dam_break(0.25, 0.08, spacing).with_solver(SolverKind::Pbf);
    let dfsph = |spacing| Scene::dam_break(0.25, 0.08, spacing).with_solver(SolverKind::Dfsph);
    let cases = if sweep {
        vec![
            ("PBF frame, 5k", pbf(0.0126), false),
            ("PBF frame, 10k", pbf(0.01), false),
            ("PBF frame, 20k", pbf(0.0079), false),
            ("PBF frame, 40k", pbf(0.0063), false),
            ("DFSPH frame, 10k", dfsph(0.01), false),
        ]
    } else {
        scaling_cases(pbf, dfsph)
    };
    if paired {
        return run_paired(&cases, &threads, count, every);
    }
    run(&cases, &threads, count, every)
}

/// Times the steps of `cases` at every thread count of `threads`, frame by
/// frame in turn (see the module docs), and prints the table.
fn run_paired(
    cases: &[(&str, Scene, bool)],
    threads: &[usize],
    count: usize,
    every: bool,
) -> Result<(), Error> {
    println!(
        "slab dam break, {count} frames of 1/60 s after 2 untimed, stepped in turn at each thread count; median ms (median per-frame speed-up over 1 thread)"
    );
    header(threads);
    for (name, scene, _) in cases {
        let pools = (threads.iter())
            .map(|&n| rayon::ThreadPoolBuilder::new().num_threads(n).build())
            .collect::<Result<Vec<_>, _>>()?;
        let mut worlds = Vec::new();
        for pool in &pools {
            worlds.push(pool.install(|| -> Result<World, Error> {
                let mut world = scene.build_world()?;
                world.use_every_thread(every);
                for _ in 0..2 {
                    world.advance(1.0 / 60.0)?;
                }
                Ok(world)
            })?);
        }
        let mut times = vec![Vec::with_capacity(count); threads.len()];
        for _ in 0..count {
            for ((pool, world), times) in pools.iter().zip(&mut worlds).zip(&mut times) {
                let start = Instant::now();
                pool.install(|| world.advance(1.0 / 60.0))?;
                times.push(start.elapsed().as_secs_f64() * 1e3);
            }
        }
        print!("{:<34}", format!("{name} ({})", worlds[0].particles.len()));
        for t in &times {
            let mut gains: Vec<f64> = times[0].iter().zip(t).map(|(a, b)| a / b).collect();
            let gain = median(&mut gains);
            print!(
                "{:>18}",
                format!("{:.2} ({gain:.2}×)", median(&mut t.clone()))
            );
        }
        println!();
    }
    Ok(())
}

/// The table's header: a column per thread count.
fn header(threads: &[usize]) {
    print!("{:<34}", "");
    for n in threads {
        print!("{:>18}", format!("{n} threads"));
    }
    println!();
}

/// The default rows: PBF at 10k and 100k (each with the extraction of its
/// last state) and DFSPH at 10k.
fn scaling_cases(
    pbf: impl Fn(f32) -> Scene,
    dfsph: impl Fn(f32) -> Scene,
) -> Vec<(&'static str, Scene, bool)> {
    vec![
        ("PBF frame, 10k", pbf(0.01), true),
        ("PBF frame, 100k", pbf(0.00455), true),
        ("DFSPH frame, 10k", dfsph(0.01), false),
    ]
}

/// Times `cases` (name, scene, whether to time its extraction too) at
/// every thread count of `threads`, `count` frames each, and prints the
/// table; with `every`, the steps use every thread of each pool.
fn run(
    cases: &[(&str, Scene, bool)],
    threads: &[usize],
    count: usize,
    every: bool,
) -> Result<(), Error> {
    println!(
        "slab dam break, {count} frames of 1/60 s after 2 untimed; median ms (speed-up over 1 thread); {}",
        if every {
            "steps on every thread of the pool"
        } else {
            "steps on at most useful_threads(n) of them"
        }
    );
    header(threads);
    for (name, scene, extract) in cases {
        let particles = scene.particles()?.len();
        let mut rows = vec![(format!("{name} ({particles})"), Vec::new())];
        if *extract {
            rows.push(("anisotropic extraction of it".to_string(), Vec::new()));
        }
        for &n in threads {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build()?;
            let (frame, world) = pool.install(|| frames(scene, count, every))?;
            rows[0].1.push(frame);
            if *extract {
                let (particles, h) = (&world.particles, world.params().h);
                rows[1].1.push(pool.install(|| extraction(particles, h))?);
            }
        }
        for (label, times) in rows {
            print!("{label:<34}");
            for t in &times {
                print!("{:>18}", format!("{t:.2} ({:.2}×)", times[0] / t));
            }
            println!();
        }
    }
    Ok(())
}
