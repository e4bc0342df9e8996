//! The anisotropic surface field (Yu & Turk 2013, `surfel_extract::anisotropy`)
//! against the targets: a settled pool's top is flat and keeps its
//! volume, a sphere keeps its volume, a one-particle sheet stays closed, and
//! the surfels are the same for any thread count.

use sph_core::glam::Vec3;
use sph_core::{Scene, SolverKind};
use surfel_extract::samples::jittered_lattice;
use surfel_extract::{
    ColourField, ExtractParams, Extractor, Surface, Surfels, coverage, extract_field,
};

/// The surfels of `field`'s kind for `positions` (Shepard volumes) at `h`,
/// with the field they came from.
fn extract(positions: &[Vec3], h: f32, surface: Surface) -> (Surfels, ColourField) {
    let params = ExtractParams {
        surface,
        ..ExtractParams::new(h)
    };
    let mut extractor = Extractor::new();
    extractor.extract_points(positions, &params).unwrap();
    let out = extractor.take();
    let mut field = ColourField::new(surface).unwrap();
    field.refill_from_positions(positions, h).unwrap();
    (out, field)
}

/// The fraction of the field's iso-surface (points on rays 0.2 h apart)
/// that the surfels cover (within 0.1 h of a disc), and the number of
/// points.
fn covered(out: &Surfels, field: &ColourField) -> (f64, usize) {
    let h = field.h();
    let points = coverage::iso_points(field, 0.5, 0.2 * h).unwrap();
    let fraction = coverage::covered_fraction(&out.surfels, &points, 0.1 * h).unwrap();
    (fraction, points.len())
}

/// The pool: 0.6 × 0.2 × 0.6 m at 2 cm (h = 4 cm, 9,000 particles),
/// settled for 2 s by DFSPH. Its top's surfels (facing up, 2h from the
/// walls) lean from vertical by at most 1° at the median (issue 28's
/// target), the surface covers all of the field's iso-surface, and it
/// encloses N m/ρ0. Measured (this test's output), anisotropic: 0.97°
/// median, 2.90° at the 99th percentile, volume 0.985, coverage 100 %;
/// isotropic: 1.52°, 4.27°, 0.991, 100 %. Asserted: the medians ≤ 1°
/// (anisotropic) and 1.75° (isotropic), the anisotropic one at least 0.4°
/// below the isotropic, the 99th percentiles ≤ 3° and 5°, the volumes
/// within 2 %, coverage ≥ 99 %. The scenes' clearance holds the particles
/// half a spacing off the floor and the four walls, and the surface,
/// which knows nothing of walls, stays off them with the particles: before
/// it the first layers sank towards the walls and the volumes read 0.990
/// and 1.001 (0.89° and 1.49° at the median), and the bound was 1.5 %.
/// On a pool settled by WCSPH, whose top is rougher, 8.9° against 11.2°
/// (`cargo run --release -p surfel-extract --example flat_pool -- wcsph`).
#[test]
fn settled_pool_is_flat_and_keeps_its_volume() {
    let scene = Scene::dam_break(0.15, 0.6, 0.02).with_solver(SolverKind::Dfsph);
    let world = settled_pool(scene.clone(), 0.2);
    let p = &world.particles;
    let h = scene.fluid.h;
    let volume: f64 = (p.masses().iter())
        .map(|&m| f64::from(m / scene.fluid.rest_density))
        .sum();
    let top = p.positions().iter().map(|x| x.y).fold(f32::MIN, f32::max);
    let mut medians = Vec::new();
    for surface in [Surface::Isotropic, Surface::anisotropic()] {
        let params = ExtractParams {
            surface,
            ..ExtractParams::new(h)
        };
        let mut extractor = Extractor::new();
        let out = extractor.extract(p, &params).unwrap().clone();
        let field = extractor.field().unwrap();
        let angles = top_angles(&out, top, h);
        assert!(
            angles.len() > 5000,
            "{surface:?}: {} top surfels",
            angles.len()
        );
        let (median, p99) = (quantile(&angles, 0.5), quantile(&angles, 0.99));
        let enclosed = coverage::enclosed_volume(field, params.iso, 0.005).unwrap() / volume;
        let (covered, points) = covered(&out, field);
        println!(
            "{surface:?}: {} top surfels, median {median:.2}°, p99 {p99:.2}°; volume {enclosed:.4} of N m/ρ0; coverage {:.2} % of {points} points",
            angles.len(),
            100.0 * covered
        );
        let isotropic = surface == Surface::Isotropic;
        assert!(points > 15_000, "{surface:?}: {points} iso-surface points");
        let (most, most_p99) = if isotropic { (1.75, 5.0) } else { (1.0, 3.0) };
        assert!(median <= most, "{surface:?}: median {median}°");
        assert!(p99 <= most_p99, "{surface:?}: 99th percentile {p99}°");
        assert!(
            (enclosed - 1.0).abs() <= 0.02,
            "{surface:?}: volume {enclosed}"
        );
        assert!(covered >= 0.99, "{surface:?}: coverage {covered}");
        medians.push(median);
    }
    assert!(
        medians[1] <= medians[0] - 0.4,
        "anisotropic median {}° against isotropic {}°",
        medians[1],
        medians[0]
    );
}

/// The pool (0.6 m square, `depth` deep, in a tank 0.2 m deeper)
/// of `scene`'s solver and spacing, settled for 2 s.
fn settled_pool(mut scene: Scene, depth: f32) -> sph_core::World {
    scene.domain.min = [0.0; 3];
    scene.domain.max = [0.6, depth + 0.2, 0.6];
    scene.blocks[0].min = [0.0; 3];
    scene.blocks[0].max = [0.6, depth, 0.6];
    let mut world = scene.build_world().unwrap();
    for _ in 0..120 {
        world.advance(1.0 / 60.0).unwrap();
    }
    world
}

/// How far the top surfels' normals lean from vertical (degrees, sorted):
/// those facing up within h of the `top` particle and more than 2h from
/// the pool's side walls.
fn top_angles(out: &Surfels, top: f32, h: f32) -> Vec<f32> {
    let mut angles: Vec<f32> = (out.surfels.iter())
        .filter(|s| {
            let (x, z) = (s.position.x, s.position.z);
            s.normal.y > 0.0
                && s.position.y > top - h
                && (2.0 * h..0.6 - 2.0 * h).contains(&x)
                && (2.0 * h..0.6 - 2.0 * h).contains(&z)
        })
        .map(|s| s.normal.y.clamp(-1.0, 1.0).acos().to_degrees())
        .collect();
    angles.sort_by(f32::total_cmp);
    angles
}

/// The `q` quantile of sorted `values`.
fn quantile(values: &[f32], q: f32) -> f32 {
    values[((values.len() - 1) as f32 * q).round() as usize]
}

/// Issue 41's target for PBF's top normals, met by its Gauss–Seidel solve
/// (`PbfSolve::GaussSeidel`) at 4 substeps of 4 sweeps: the pool above,
/// 0.2 m and 0.5 m (25 layers) deep, settled by PBF for 2 s, the default
/// anisotropic surface's top normals lean at most 1° at the median and 5°
/// at the 99th percentile. Measured (`cargo run --release -p
/// surfel-extract --example flat_pool -- pbf --depth D --solver-toml 'pbf
/// = { solve = "gauss-seidel", substeps = 4, iterations = 4 }'`): 0.96°
/// and 2.77° at 0.2 m, 0.97° and 2.68° at 0.5 m. At 4 substeps of 3
/// sweeps 0.96° and 2.42° at 0.2 m but 1.05° and 2.77° at 0.5 m; at the
/// default 3 × 3, 1.03° and 2.85° at 0.2 m. Under the default Jacobi
/// solve (3 × 3) 2.71° and 9.20° at 0.2 m, 3.16° and 9.08° at 0.5 m; this
/// test checks Jacobi's shallow pool stays above 2° and 5°, so that it
/// shows the solve's difference.
#[test]
fn a_pool_settled_by_pbf_gauss_seidel_is_flat() {
    use sph_core::{PbfParams, PbfSolve};
    for (solve, depth) in [
        (PbfSolve::GaussSeidel, 0.2),
        (PbfSolve::GaussSeidel, 0.5),
        (PbfSolve::Jacobi, 0.2),
    ] {
        let mut scene = Scene::dam_break(0.15, 0.6, 0.02).with_solver(SolverKind::Pbf);
        scene.solver.pbf = Some(match solve {
            PbfSolve::GaussSeidel => PbfParams {
                solve,
                substeps: 4,
                iterations: 4,
                ..PbfParams::default()
            },
            PbfSolve::Jacobi => PbfParams::default(),
        });
        let world = settled_pool(scene.clone(), depth);
        let p = &world.particles;
        let h = scene.fluid.h;
        let top = p.positions().iter().map(|x| x.y).fold(f32::MIN, f32::max);
        let mut extractor = Extractor::new();
        let params = ExtractParams::new(h).anisotropic();
        let out = extractor.extract(p, &params).unwrap();
        let angles = top_angles(out, top, h);
        assert!(
            angles.len() > 5000,
            "{solve:?}, {depth} m: {} top surfels",
            angles.len()
        );
        let (median, p99) = (quantile(&angles, 0.5), quantile(&angles, 0.99));
        println!(
            "{solve:?}, {depth} m: {} top surfels, median {median:.2}°, p99 {p99:.2}°",
            angles.len()
        );
        if solve == PbfSolve::GaussSeidel {
            assert!(median <= 1.0 && p99 <= 5.0, "{depth} m: {median}°, {p99}°");
        } else {
            assert!(median > 2.0 && p99 > 5.0, "Jacobi: {median}°, {p99}°");
        }
    }
}

/// A jittered ball of 0.1 m radius at 1 cm (h = 2 cm), each particle's
/// volume s³: both surfaces enclose N s³ within 2 % and cover their
/// iso-surfaces. Measured: 0.987 anisotropic, 0.986 isotropic. With
/// Shepard volumes (what bare points get) both swell, 1.037 and 1.074:
/// the boundary's particles get the larger volumes.
#[test]
fn sphere_keeps_its_volume() {
    let s = 0.01;
    let ball = jittered_lattice(11, s, 0.3, 7, |x| x.length() <= 0.1);
    let volumes = vec![s * s * s; ball.len()];
    let nominal = ball.len() as f64 * f64::from(s).powi(3);
    for surface in [Surface::Isotropic, Surface::anisotropic()] {
        let mut field = ColourField::new(surface).unwrap();
        field.refill_with_volumes(&ball, &volumes, 2.0 * s).unwrap();
        let out = extract_field(&field, &ExtractParams::new(2.0 * s)).unwrap();
        let v = coverage::enclosed_volume(&field, 0.5, 0.002).unwrap() / nominal;
        let (covered, points) = covered(&out, &field);
        println!(
            "{surface:?}: ball of {} particles, enclosed volume {v:.4} of N s³, coverage {:.2} % of {points} points",
            ball.len(),
            100.0 * covered
        );
        assert!(points > 9_000, "{surface:?}: {points} iso-surface points");
        assert!((v - 1.0).abs() <= 0.02, "{surface:?}: volume {v} of N s³");
        assert!(covered >= 0.99, "{surface:?}: coverage {covered}");
    }
}

/// A sheet one particle thick (30 × 30 at 1 cm, h = 2 cm) stays one
/// closed surface: every vertical ray through its inside (the particles
/// more than h from its edges, on a lattice 0.37 cm apart offset from
/// them) crosses c = 0.5 exactly twice, once above the
/// sheet and once below, and the surfels cover at least 99 % of those
/// crossings and of the whole iso-surface. A hole would leave a ray with
/// no crossing, a sheet split in two layers a ray with four.
#[test]
fn one_particle_sheet_stays_closed() {
    let s = 0.01;
    let sheet: Vec<Vec3> = (0..900)
        .map(|k| Vec3::new((k % 30) as f32, 0.0, (k / 30) as f32) * s)
        .collect();
    let h = 2.0 * s;
    let at = |i: usize| h + 0.0013 + 0.0037 * i as f32;
    let rays: Vec<(f32, f32)> = (0..68)
        .flat_map(|i| (0..68).map(move |k| (at(i), at(k))))
        .collect();
    // The lattice spans the inside: its last ray within a step of 0.29 − h.
    let inside = 0.29 - h;
    assert!(at(67) < inside && at(68) >= inside);
    for surface in [Surface::Isotropic, Surface::anisotropic()] {
        let (out, field) = extract(&sheet, h, surface);
        let mut crossings = Vec::new();
        for &(x, z) in &rays {
            let found = crossings_along_y(&field, x, z, 2.0 * h, h / 64.0);
            assert!(
                found.len() == 2 && found[0] < 0.0 && found[1] > 0.0,
                "{surface:?}: the ray at x = {x}, z = {z} crosses c = 0.5 at y = {found:?}"
            );
            crossings.extend(found.iter().map(|&y| Vec3::new(x, y, z)));
        }
        let on_rays = coverage::covered_fraction(&out.surfels, &crossings, 0.1 * h).unwrap();
        let (covered, points) = covered(&out, &field);
        println!(
            "{surface:?}: sheet of 900, {} surfels; {} rays cross twice, {:.2} % of the crossings covered; \
             coverage {:.2} % of {points} points",
            out.surfels.len(),
            rays.len(),
            100.0 * on_rays,
            100.0 * covered
        );
        assert!(on_rays >= 0.99, "{surface:?}: crossings covered {on_rays}");
        assert!(points > 10_000, "{surface:?}: {points} iso-surface points");
        assert!(covered >= 0.99, "{surface:?}: coverage {covered}");
    }
}

/// Where c − 0.5 changes sign along the vertical line through (x, z) from
/// y = −`reach` to `reach`, in steps of `step`, each located by bisection.
fn crossings_along_y(field: &ColourField, x: f32, z: f32, reach: f32, step: f32) -> Vec<f32> {
    let f = |y: f32| field.sample(Vec3::new(x, y, z)).c - 0.5;
    let n = (2.0 * reach / step).ceil() as usize;
    let mut out = Vec::new();
    let (mut y0, mut f0) = (-reach, f(-reach));
    for k in 1..=n {
        let y1 = -reach + k as f32 * step;
        let f1 = f(y1);
        if (f0 > 0.0) != (f1 > 0.0) {
            let (mut a, mut b, fa) = (y0, y1, f0);
            for _ in 0..30 {
                let m = 0.5 * (a + b);
                if (f(m) > 0.0) == (fa > 0.0) {
                    a = m;
                } else {
                    b = m;
                }
            }
            out.push(0.5 * (a + b));
        }
        (y0, f0) = (y1, f1);
    }
    out
}

/// Bitwise the same surfels for 1, 2, 3, 4 and 7 threads.
#[test]
fn same_surfels_for_any_thread_count() {
    let s = 0.01;
    let blob = jittered_lattice(8, s, 0.4, 3, |x| {
        x.length() <= 0.07 || (x.y < -0.03 && x.x > 0.0)
    });
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let (out, _) = extract(&blob, 2.0 * s, Surface::anisotropic());
                (out.surfels.iter())
                    .flat_map(|x| {
                        [x.position.to_array(), x.normal.to_array()]
                            .concat()
                            .into_iter()
                            .map(f32::to_bits)
                    })
                    .collect::<Vec<_>>()
            })
    };
    let one = run(1);
    assert!(!one.is_empty());
    for threads in [2, 3, 4, 7] {
        assert!(one == run(threads), "{threads} threads differ from 1");
    }
}
