//! A settled pool's top surface under each surface field: how far its
//! surfels' normals lean from vertical, and the volume the surface encloses
//! against the particles' N m/ρ0.
//!
//! `cargo run --release -p surfel-extract --example flat_pool [-- SOLVER
//! [--solver-toml 'pbf = { ... }'] [--depth D]]`
//!
//! The pool: 0.6 × 0.2 × 0.6 m of water at 2 cm spacing (h = 4 cm) in a
//! 0.6 × 0.4 × 0.6 m tank (`--depth D`: D deep, in a tank 0.2 m deeper),
//! settled for 2 s by DFSPH, or by the solver named (`wcsph`, `pbf`,
//! `dfsph`), with the body of a `[solver]` table (without `kind`) where
//! given.

use std::time::Instant;

use sph_core::scene::SolverSpec;
use sph_core::{Scene, SolverKind, World};
use surfel_extract::anisotropy::Centres;
use surfel_extract::{Anisotropy, ExtractParams, Extractor, Surface, coverage};

/// The pool, `depth` deep, settled by `kind` with the solver parameters of
/// `spec`.
pub fn settled_pool(kind: SolverKind, spec: SolverSpec, depth: f32) -> (Scene, World) {
    let spacing = 0.02;
    let mut scene = Scene::dam_break(0.15, 0.6, spacing);
    scene.solver = SolverSpec { kind, ..spec };
    scene.domain.min = [0.0; 3];
    scene.domain.max = [0.6, depth + 0.2, 0.6];
    scene.blocks[0].min = [0.0; 3];
    scene.blocks[0].max = [0.6, depth, 0.6];
    let mut world = scene.build_world().expect("the pool builds");
    for _ in 0..120 {
        world.advance(1.0 / 60.0).expect("the pool settles");
    }
    (scene, world)
}

/// The median, 90th and 99th percentile of `angles`.
fn percentiles(mut angles: Vec<f32>) -> [f32; 3] {
    angles.sort_by(f32::total_cmp);
    let at = |q: f32| angles[((angles.len() - 1) as f32 * q).round() as usize];
    [at(0.5), at(0.9), at(0.99)]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let spec: SolverSpec = match args.iter().position(|a| a == "--solver-toml") {
        Some(at) => {
            let text = args.get(at + 1).map(String::as_str).unwrap_or_default();
            toml::from_str(text).unwrap_or_else(|e| {
                eprintln!("--solver-toml: {e}");
                std::process::exit(2);
            })
        }
        None => SolverSpec::default(),
    };
    let kind = match args.get(1).map(String::as_str) {
        None | Some("dfsph") => SolverKind::Dfsph,
        Some("wcsph") => SolverKind::Wcsph,
        Some("pbf") => SolverKind::Pbf,
        Some(other) => {
            eprintln!("unknown solver {other:?}: wcsph, pbf or dfsph");
            std::process::exit(2);
        }
    };
    let start = Instant::now();
    let depth = match args.iter().position(|a| a == "--depth") {
        Some(at) => match args.get(at + 1).and_then(|d| d.parse::<f32>().ok()) {
            Some(d) if d > 0.0 && d <= 1.0 => d,
            _ => {
                eprintln!("--depth: a depth in (0, 1] m");
                std::process::exit(2);
            }
        },
        None => 0.2,
    };
    let (scene, world) = settled_pool(kind, spec, depth);
    let p = &world.particles;
    let h = scene.fluid.h;
    let volume: f64 = p
        .masses()
        .iter()
        .map(|&m| f64::from(m / scene.fluid.rest_density))
        .sum();
    let top = p.positions().iter().map(|x| x.y).fold(f32::MIN, f32::max);
    println!(
        "{kind}: {} particles settled in {:.1} s; top particle at {top:.4} m; N m/ρ0 = {volume:.5} m³",
        p.len(),
        start.elapsed().as_secs_f32()
    );
    println!(
        "| field | surfels | discarded | coverage | median |c − iso| | top surfels | median | p90 | p99 | volume / N m/ρ0 | extraction |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let paper = Anisotropy {
        centres: Centres::Mean,
        ..Anisotropy::default()
    };
    let fields = [
        ("isotropic (thesis)", Surface::Isotropic),
        (
            "anisotropic (default: layer smoothing, r = 1.5h)",
            Surface::anisotropic(),
        ),
        (
            "anisotropic, the paper's mean smoothing",
            Surface::Anisotropic(paper),
        ),
        (
            "anisotropic, r = 2h (the paper's)",
            Surface::Anisotropic(Anisotropy {
                radius: 2.0,
                ..Anisotropy::default()
            }),
        ),
        (
            "anisotropic, r = h",
            Surface::Anisotropic(Anisotropy {
                radius: 1.0,
                ..Anisotropy::default()
            }),
        ),
        (
            "anisotropic, no smoothing (λ = 0)",
            Surface::Anisotropic(Anisotropy {
                smoothing: 0.0,
                ..Anisotropy::default()
            }),
        ),
    ];
    for (name, surface) in fields {
        let params = ExtractParams {
            surface,
            ..ExtractParams::new(h)
        };
        let mut extractor = Extractor::new();
        let t = Instant::now();
        let out = extractor.extract(p, &params).expect("extracts").clone();
        let time = t.elapsed();
        let field = extractor.field().expect("built");
        // The top: facing up, above the top particle less h, h from the walls.
        let angles: Vec<f32> = (out.surfels.iter())
            .filter(|s| {
                s.normal.y > 0.0
                    && s.position.y > top - h
                    && s.position.x > 2.0 * h
                    && s.position.x < 0.6 - 2.0 * h
                    && s.position.z > 2.0 * h
                    && s.position.z < 0.6 - 2.0 * h
            })
            .map(|s| s.normal.y.clamp(-1.0, 1.0).acos().to_degrees())
            .collect();
        let count = angles.len();
        let [median, p90, p99] = percentiles(angles);
        let enclosed =
            coverage::enclosed_volume(field, params.iso, 0.005).expect("a small lattice");
        let points = coverage::iso_points(field, params.iso, 0.01).expect("a small lattice");
        let covered = coverage::covered_fraction(&out.surfels, &points, 0.1 * h)
            .expect("finite surfels and an iso-surface");
        let residual = coverage::residuals(field, params.iso, &out.surfels).median;
        println!(
            "| {name} | {} | {} | {:.2} % | {residual:.4} | {count} | {median:.2}° | {p90:.2}° | {p99:.2}° | {:.3} | {:.0} ms |",
            out.stats.surfels,
            out.stats.discarded,
            100.0 * covered,
            enclosed / volume,
            time.as_secs_f64() * 1e3
        );
    }
}
